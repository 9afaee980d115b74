# Shared by the training recipes (scripts/recipe_geometry.sh, scripts/recipe_text.sh):
# the device line, RECIPE.md records and resumable training chunks. The sourcing script sets
# SEED, DATA, VERSION, PRESET, THREADS and CHUNK_MIN.

device() {
  python - <<'EOF'
import platform, os
try:
    import torch
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none"
except Exception:
    gpu = "unknown"
cpu = platform.processor() or platform.machine()
try:
    for line in open("/proc/cpuinfo"):
        if line.startswith("model name"):
            cpu = line.split(":", 1)[1].strip()
            break
except OSError:
    pass
print(f"{cpu}, {os.cpu_count()} cores visible, GPU {gpu}")
EOF
}

record() {   # record FOLDER TEXT...: append a line to FOLDER/RECIPE.md
  local dir=$1; shift
  mkdir -p "$dir"
  local version=$VERSION
  [ -f "$DATA/manifest.json" ] && version=$(python -c "import json, sys; print(json.load(open(sys.argv[1])).get('data_version', ''))" "$DATA/manifest.json")
  [ -f "$dir/RECIPE.md" ] || printf '# How this folder was made\n\nseed %s, data %s (data_version %s), preset %s, device: %s\n\n' \
    "$SEED" "$DATA" "$version" "$PRESET" "$(device)" > "$dir/RECIPE.md"
  printf -- '- %s\n' "$*" >> "$dir/RECIPE.md"
}

ckpt_step() {   # ckpt_step FILE: the step stored in a run checkpoint (0 when absent)
  [ -f "$1" ] || { echo 0; return; }
  python -c "import sys; from model.core.checkpoint import load_weights_only as l; print(int(l(sys.argv[1]).get('step', 0)))" "$1"
}

run_ckpt() {   # run_ckpt KIND OUT: the resumable checkpoint of a run of that trainer
  case "$1" in sdf|prior) echo "$2/ckpt.pt" ;; *) echo "$2/last.pt" ;; esac
}

train_chunks() {   # train_chunks KIND OUT STEPS ARGS...: resumable chunks of <= CHUNK_MIN min
  local kind=$1 out=$2 steps=$3; shift 3
  local ckpt; ckpt=$(run_ckpt "$kind" "$out")
  local cmd=(artformer train "$kind" --data "$DATA" --preset "$PRESET" --out "$out"
             --seed "$SEED" --threads "$THREADS" --steps "$steps" --no-progress
             --chunk-minutes "$CHUNK_MIN" --resume "$@")
  while [ "$(ckpt_step "$ckpt")" -lt "$steps" ]; do
    local t0; t0=$(date -u +%s)
    local before; before=$(ckpt_step "$ckpt")
    echo "[recipe] $(date -u +%FT%TZ) ${cmd[*]} (from step $before, at most $CHUNK_MIN min)"
    set +e
    # --chunk-minutes stops the process cleanly with its checkpoint; timeout is only a
    # backstop (loading the cached box-frame samples comes before the loop's clock starts)
    timeout --signal=TERM "$(( (CHUNK_MIN + ${PREP_MIN:-10}) * 60 ))" "${cmd[@]}"
    local rc=$?
    set -e
    local after; after=$(ckpt_step "$ckpt")
    record "$out" "$(date -u +%FT%TZ) \`${cmd[*]}\`: steps $before -> $after, $(( $(date -u +%s) - t0 )) s wall, exit $rc"
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ]; then
      echo "[recipe] training failed (exit $rc); fix it and run the recipe again" >&2
      exit "$rc"
    fi
    if [ "$after" -le "$before" ]; then
      echo "[recipe] no checkpoint progress in one chunk; raise CHUNK_MIN or lower ckpt_every" >&2
      exit 1
    fi
    if [ "${ONE_CHUNK:-0}" = 1 ]; then echo "[recipe] ONE_CHUNK=1: stopping after one chunk"; exit 0; fi
  done
  return 0
}

