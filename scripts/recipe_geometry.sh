#!/usr/bin/env bash
# Retraining recipe of the shape prior (tri-plane SDF auto-encoder + codebook diffusion prior)
# on current procedural data. Every stage is resumable: run this script again after an
# interruption and it continues where it stopped (finished stages are skipped, training
# resumes from OUT/ckpt.pt). No stage runs longer than CHUNK_MIN minutes in one go.
#
#   bash scripts/recipe_geometry.sh              # everything: data, auto-encoder, prior, eval
#   STAGE=sdf bash scripts/recipe_geometry.sh    # one stage: data | cache | sdf | prior | eval | export
#
# Settings (environment variables, defaults below): N_OBJECTS, SEED, VERSION, PRESET,
# SDF_STEPS, PRIOR_STEPS, THREADS, BANK_PER_TEXT, CHUNK_MIN, RUNS, DEVICE, CODES_FROM,
# CODES_SDF (CODES_FROM=model/weights/prior_small.pt: a prior the shipped text and image models
# run with unchanged, `train prior --codes-from`; docs/geometry.md). Each run folder gets
# RECIPE.md with the command lines, seed, data version, device and wall times of every chunk.
# DEVICE=auto trains the auto-encoder on CUDA where torch sees a GPU (a CUDA build of torch;
# the pinned CPU wheel sees none) and records the GPU in the checkpoint; the prior stays on
# the CPU.
#
# Why these settings: docs/geometry.md, "How good it is". Estimated wall time on 2 CPU
# cores: in the RECIPE block of docs/geometry.md.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/env.sh

N_OBJECTS=${N_OBJECTS:-10000}
SEED=${SEED:-0}
VERSION=${VERSION:-synth-v6}
NAME=${NAME:-v6}
PRESET=${PRESET:-small-fine}
SDF_STEPS=${SDF_STEPS:-26000}
PRIOR_STEPS=${PRIOR_STEPS:-20000}
THREADS=${THREADS:-2}
BANK_PER_TEXT=${BANK_PER_TEXT:-400}    # retrieval latents kept per label in the exported prior
DEVICE=${DEVICE:-auto}                 # the auto-encoder's: cpu | cuda | auto
CODES_FROM=${CODES_FROM:-}             # prior: adopt this prior's code space (e.g. the shipped
CODES_SDF=${CODES_SDF:-model/weights/sdf_small.pt}   # model/weights/prior_small.pt) and its AE
CHUNK_MIN=${CHUNK_MIN:-140}            # training minutes per invocation (+ <= 10 min loading: <= 2.5 h)
RUNS=${RUNS:-runs/geometry_${NAME}}
STAGE=${STAGE:-all}
SYNTH=data/synth/$NAME
DATA=data/prepared/$NAME
SDF_RUN=$RUNS/sdf_$PRESET
PRIOR_RUN=$RUNS/prior_$PRESET
mkdir -p "$RUNS"
if ! python -c "from model.geometry.config import get_preset; get_preset('$PRESET')" 2>/dev/null; then
  cat >&2 <<EOF
[recipe] preset '$PRESET' is not in model/geometry/config.py. The measured cause of broken walls
is the 32x32 tri-plane (docs/geometry.md, "How good it is"); the fine preset is 'small' with
  sdf=SDFConfig(plane_res=64, vae_channels=(32, 64, 64, 64))
(same z_dim 256, so the prior and the transformer's code layout are unchanged). Add it to
_presets() under the name '$PRESET', or run with PRESET=small to retrain the shipped sizes.
EOF
  exit 2
fi

source scripts/recipe_lib.sh

stage_data() {
  if [ ! -f "$DATA/manifest.json" ] || [ "$(ls "$DATA/objects" 2>/dev/null | wc -l)" -lt "$N_OBJECTS" ]; then
    local t0; t0=$(date -u +%s)
    artformer data synth --n "$N_OBJECTS" --out "$SYNTH" --seed "$SEED" --workers "$THREADS"
    artformer data prepare --src "$SYNTH" --out "$DATA" --workers "$THREADS" --version "$VERSION" --seed "$SEED"
    record "$RUNS" "$(date -u +%FT%TZ) data: \`artformer data synth --n $N_OBJECTS --out $SYNTH --seed $SEED\` + \`artformer data prepare --src $SYNTH --out $DATA --version $VERSION --seed $SEED\`: $(( $(date -u +%s) - t0 )) s wall"
  fi
}

stage_cache() {   # the one-time exact box-frame re-sampling of train/val, cached in SDF_RUN/cache
  local t0; t0=$(date -u +%s)
  python - "$DATA" "$PRESET" "$SEED" "$SDF_RUN/cache" "$THREADS" <<'EOF'
import sys
from model.geometry.config import get_preset
from model.geometry.data import load_parts
data, preset, seed, cache = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
max_sdf = get_preset(preset).sdf_train.max_sdf
for split in ("train", "val"):   # resumable: finished shards of 128 objects are kept
    p = load_parts(data, split, progress=True, max_sdf=max_sdf, seed=seed, cache_dir=cache,
                   workers=int(sys.argv[5]))
    print(f"{split}: {len(p)} parts cached in {cache}")
EOF
  record "$SDF_RUN" "$(date -u +%FT%TZ) box-frame samples of $DATA cached in $SDF_RUN/cache: $(( $(date -u +%s) - t0 )) s wall"
}

stage_sdf()   { ls "$SDF_RUN"/cache/parts_val_*.pt >/dev/null 2>&1 || stage_cache
                train_chunks sdf "$SDF_RUN" "$SDF_STEPS" --device "$DEVICE"; }
stage_prior() {
  if [ -n "$CODES_FROM" ]; then   # keep the shipped transformers: the prior reads their codes
    train_chunks prior "$PRIOR_RUN" "$PRIOR_STEPS" --sdf "$SDF_RUN/ckpt.pt" \
      --codes-from "$CODES_FROM" --codes-sdf "$CODES_SDF"
  else
    train_chunks prior "$PRIOR_RUN" "$PRIOR_STEPS" --sdf "$SDF_RUN/ckpt.pt"
  fi
}

stage_eval() {   # validation only, new weights and the shipped ones side by side; the test
                 # split is scored once, for the weights that ship (docs/geometry.md)
  local t0; t0=$(date -u +%s)
  local args=(--data "$DATA" --split val --per-label 30 --samples-per-label 8)
  artformer eval geometry "${args[@]}" --sdf "$SDF_RUN/ckpt.pt" --prior "$PRIOR_RUN/ckpt.pt" \
    --json "$RUNS/eval_geometry_val.json" --figures "$RUNS/figures"
  artformer eval geometry "${args[@]}" --json "$RUNS/eval_geometry_val_shipped.json"
  record "$RUNS" "$(date -u +%FT%TZ) eval: \`artformer eval geometry ${args[*]}\` with --sdf $SDF_RUN/ckpt.pt --prior $PRIOR_RUN/ckpt.pt and with the shipped weights: $(( $(date -u +%s) - t0 )) s wall"
}

stage_export() {   # stripped fp16 copies beside the runs (committing them is a separate step)
  python -c "from model.geometry.train import export_weights as e; \
e('$SDF_RUN/ckpt.pt', '$RUNS/sdf_$PRESET.pt', 'sdf'); \
e('$PRIOR_RUN/ckpt.pt', '$RUNS/prior_$PRESET.pt', 'prior', $BANK_PER_TEXT, $SEED)"
  record "$RUNS" "$(date -u +%FT%TZ) export: $RUNS/sdf_$PRESET.pt, $RUNS/prior_$PRESET.pt" \
    "(retrieval bank: at most $BANK_PER_TEXT latents per label)"
}

case "$STAGE" in
  all) stage_data; stage_sdf; stage_prior; stage_eval; stage_export ;;
  data|cache|sdf|prior|eval|export) "stage_$STAGE" ;;
  *) echo "STAGE must be all|data|cache|sdf|prior|eval|export, got $STAGE" >&2; exit 2 ;;
esac
