#!/usr/bin/env bash
# Retraining recipe of the text model (articulation transformer) and then the image model on
# top of it, against a shape prior retrained by scripts/recipe_geometry.sh. Every stage is
# resumable: run the script again after an interruption and it continues where it stopped
# (training resumes from OUT/last.pt); no training process runs longer than CHUNK_MIN minutes.
#
#   bash scripts/recipe_text.sh                 # text, text-eval, render, image, image-eval
#   STAGE=text bash scripts/recipe_text.sh      # one stage: text | text-eval | render | image | image-eval
#
# Settings (environment variables, defaults below): DATA, PRIOR, SDF, PRESET, TEXT_STEPS,
# IMAGE_STEPS, TRUNK, FRAME, MODES, PLACE, SEED, THREADS, CHUNK_MIN, RUNS, INIT, LR. INIT starts
# the text model from a finished checkpoint (a fine-tune, e.g. onto another shape prior's
# targets). FRAME, MODES and PLACE are the token frame, the articulation modes and the place
# classes (PLACE=1: --place-bins; docs/results/layout_training.md).
# Each run folder gets RECIPE.md with the command lines, seed, data version, device and wall
# time of every chunk.
# Nothing is copied into model/weights: the fp16 files land in RUNS, to be shipped only when
# they beat the shipped ones on validation data.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/env.sh

NAME=${NAME:-v6}                         # the data: synth-8 objects (v5's trees, solid bottles)
DATA=${DATA:-data/prepared/$NAME}
RENDERS=${RENDERS:-data/renders/$NAME}
# an earlier render folder whose views stand in for objects that did not change (byte-identical
# to rendering them; `artformer data render --reuse`); skipped when it is not there
RENDER_REUSE=${RENDER_REUSE:-data/renders/v5}
GEOMETRY=${GEOMETRY:-runs/geometry_v6}   # the shape prior, trained on synth-v6 parts
PRESET=${PRESET:-small}
PRIOR=${PRIOR:-$GEOMETRY/prior_small-fine.pt}
SDF=${SDF:-$GEOMETRY/sdf_small-fine.pt}
TEXT_STEPS=${TEXT_STEPS:-16000}  # batch 64: 128 passes over 8,000 training trees
IMAGE_STEPS=${IMAGE_STEPS:-12000}
TRUNK=${TRUNK:-model/weights/image_small.pt}   # fine-tuned encoder blocks 4-14 (its trunk)
FRAME=${FRAME:-parent}
MODES=${MODES:-4}
PLACE=${PLACE:-0}
SEED=${SEED:-0}
THREADS=${THREADS:-2}
CHUNK_MIN=${CHUNK_MIN:-120}     # training minutes per invocation; + PREP_MIN of loading <= 2.5 h
PREP_MIN=${PREP_MIN:-30}        # a first chunk encodes every description and target (~25 min)
RUNS=${RUNS:-runs/text_${NAME}}
STAGE=${STAGE:-all}
INIT=${INIT:-}                  # a finished text checkpoint to fine-tune from (empty: scratch)
LR=${LR:-5e-4}
VERSION=${VERSION:-}
TEXT_RUN=$RUNS/transformer
IMAGE_RUN=$RUNS/image
for f in "$DATA/manifest.json" "$PRIOR" "$SDF"; do
  if [ ! -f "$f" ]; then
    echo "[recipe] $f is missing: build the data (NAME=$NAME VERSION=synth-$NAME STAGE=data" \
         "bash scripts/recipe_geometry.sh) and the shape prior (bash scripts/recipe_geometry.sh)" \
         "first, or set DATA / PRIOR / SDF" >&2
    exit 2
  fi
done
mkdir -p "$RUNS"
source scripts/recipe_lib.sh

# --minutes 0: no wall-clock budget (the small preset's 24 minutes would end the run and
# anneal its learning rate by time); the schedule follows the steps alone
common=(--prior "$PRIOR" --sdf "$SDF" --lr "$LR" --own-inputs 0.5 --token-frame "$FRAME"
        --art-modes "$MODES" --minutes 0)
if [ -n "$INIT" ]; then common+=(--init "$INIT"); fi
if [ "$PLACE" = 1 ]; then common+=(--place-bins); fi

stage_text() {
  train_chunks transformer "$TEXT_RUN" "$TEXT_STEPS" "${common[@]}"
  # the finished run once more: no step left, so it only writes transformer.pt and the copy
  artformer train transformer --data "$DATA" --preset "$PRESET" --out "$TEXT_RUN" --seed "$SEED" \
    --threads "$THREADS" --steps "$TEXT_STEPS" --no-progress --resume "${common[@]}" \
    --half "$RUNS/transformer_$PRESET.pt"
  record "$TEXT_RUN" "$(date -u +%FT%TZ) export: $RUNS/transformer_$PRESET.pt (fp16)"
}

stage_text_eval() {   # validation only: the test split is scored once, for the shipped file
  local t0; t0=$(date -u +%s)
  artformer train transformer --eval "$RUNS/transformer_$PRESET.pt" --data "$DATA" --split val \
    --temperature 0.3 --follow-plan --no-progress --json "$RUNS/text_alignment_val.json"
  mkdir -p "$RUNS/candidate"
  ln -sf "$(realpath "$RUNS/transformer_$PRESET.pt")" "$RUNS/candidate/transformer_$PRESET.pt"
  ln -sf "$(realpath "$SDF")" "$RUNS/candidate/sdf_$PRESET.pt"
  ln -sf "$(realpath "$PRIOR")" "$RUNS/candidate/prior_$PRESET.pt"
  artformer eval layout --data "$DATA" --split val --n 100 --checkpoint "$RUNS/candidate" \
    --out "$RUNS/layout_val.json"
  # the shipped model on the same validation objects, to decide on
  artformer train transformer --eval model/weights/transformer_$PRESET.pt --data "$DATA" \
    --split val --temperature 0.3 --follow-plan --no-progress \
    --json "$RUNS/text_alignment_val_shipped.json"
  artformer eval layout --data "$DATA" --split val --n 100 --out "$RUNS/layout_val_shipped.json"
  # what users see, candidate and shipped: the audit (raw and refined), free-form and dev
  # prompts (the held-out prompts are scored once, for the model that ships)
  local ck set
  for ck in candidate shipped; do
    local opt=(); [ "$ck" = candidate ] && opt=(--checkpoint "$RUNS/candidate")
    artformer eval audit --seeds 6 --rows raw,refined \
      --freeform-file model/metrics/prompts_bench.txt --out "$RUNS/audit_$ck" "${opt[@]}"
    for set in freeform dev; do
      artformer eval --freeform-only --seeds 3 --freeform-file "model/metrics/prompts_$set.txt" \
        --json "$RUNS/${set}_$ck.json" "${opt[@]}"
    done
    python scripts/bare_names.py --json "$RUNS/bare_$ck.json" "${opt[@]}"
  done
  record "$RUNS" "$(date -u +%FT%TZ) text-eval (val alignment and layout, audit, free-form and dev prompts, bare names; candidate and shipped): $(( $(date -u +%s) - t0 )) s wall"
  # the ship rule on those files (scripts/compare_candidate.py): a table and a verdict
  python scripts/compare_candidate.py "$RUNS" --markdown "$RUNS/compare_val.md"
}

stage_render() {   # resumable: objects already rendered are skipped
  local t0 reuse=(); t0=$(date -u +%s)
  if [ -f "$RENDER_REUSE/manifest.json" ]; then reuse=(--reuse "$RENDER_REUSE"); fi
  artformer data render --data "$DATA" --out "$RENDERS" --views 8 --workers "$THREADS" "${reuse[@]}"
  record "$RUNS" "$(date -u +%FT%TZ) renders: \`artformer data render --data $DATA --out $RENDERS --views 8 ${reuse[*]}\`: $(( $(date -u +%s) - t0 )) s wall"
}

stage_image() {
  local img=(--renders "$RENDERS" --init "$RUNS/transformer_$PRESET.pt" --prior "$PRIOR"
             --sdf "$SDF" --trunk "$TRUNK" --lr 2e-4 --warmup 100 --own-inputs 0.5 --minutes 0)
  train_chunks image "$IMAGE_RUN" "$IMAGE_STEPS" "${img[@]}"
  artformer train image --data "$DATA" --preset "$PRESET" --out "$IMAGE_RUN" --seed "$SEED" \
    --threads "$THREADS" --steps "$IMAGE_STEPS" --no-progress --resume "${img[@]}" \
    --half "$RUNS/image_$PRESET.pt"
  record "$IMAGE_RUN" "$(date -u +%FT%TZ) export: $RUNS/image_$PRESET.pt (fp16)"
}

stage_image_eval() {
  artformer train image --eval "$RUNS/image_$PRESET.pt" --data "$DATA" --renders "$RENDERS" \
    --split val --eval-views 0,1,2,3 --temperature 0 --json "$RUNS/image_val.json"
}

case "$STAGE" in
  all) stage_text; stage_text_eval; stage_render; stage_image; stage_image_eval ;;
  text|text-eval|render|image|image-eval) "stage_${STAGE//-/_}" ;;
  *) echo "STAGE must be all|text|text-eval|render|image|image-eval, got $STAGE" >&2; exit 2 ;;
esac
