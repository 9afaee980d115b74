#!/usr/bin/env bash
# The auto-encoder stage of scripts/recipe_geometry.sh on a lent GPU machine (one command of at
# most 10 minutes): unpack the pure-Python/extension dependencies the image lacks, rebuild a
# train-split subset of the procedural data (the current generator) on its CPU cores
# (scripts/device_data.py), train the PRESET (small-fine) auto-encoder on CUDA and leave the
# resumable checkpoint in pieces under $OUT.
#
#   bash scripts/device_pack.sh    # here, once: .devrun/devsite.tar.xz and .devrun/train_ids.txt
#   bash scripts/device_sdf.sh     # there (device run, carry .devrun), with $OUT set
#
# Settings: PRESET, SYNTH_S (seconds of synthesis), STEPS, BATCH, DEADLINE_S (seconds after
# start by which training has stopped). Back home: cat sdf_ckpt.part* > runs/.../ckpt.pt, then
# the prior in the shipped code space (the shipped text and image models keep working):
# CODES_FROM=model/weights/prior_small.pt STAGE=prior bash scripts/recipe_geometry.sh
set -uo pipefail
T0=$(date +%s)
PRESET=${PRESET:-small-fine}
SYNTH_S=${SYNTH_S:-150}; STEPS=${STEPS:-6500}; BATCH=${BATCH:-64}; DEADLINE_S=${DEADLINE_S:-550}
W=$(nproc); DEV=${DEV:-cuda}
left() { echo $(( T0 + DEADLINE_S - $(date +%s) )); }
[ "${SITE:-1}" = 1 ] && { tar xJf .devrun/devsite.tar.xz -C /tmp || exit 3; }
export PYTHONPATH=/tmp/devsite:$PWD PYTHONUNBUFFERED=1 HF_HUB_OFFLINE=1
PYMAIN='import sys; from model.cli import main; sys.exit(main(sys.argv[1:]))'   # artformer
af() { python3 -c "$PYMAIN" "$@"; }
{ nvidia-smi -L
  python3 -c "import torch, numpy; print('torch', torch.__version__, 'numpy', numpy.__version__,
                                          'cuda', torch.cuda.is_available())"
  echo "cores $W"; } | tee "$OUT/device.txt"

# smoke: the whole path on a few objects and the tiny preset, so a broken step costs seconds
head -12 .devrun/train_ids.txt > /tmp/smoke_ids.txt
python3 scripts/device_data.py /tmp/smoke_ids.txt /tmp/smoke 20 "$W" || exit 4
af train sdf --data /tmp/smoke/prepared --preset tiny --out /tmp/smoke/sdf --steps 20 \
  --no-progress --device "$DEV" --threads "$W" || exit 5
echo "smoke ok at $(( $(date +%s) - T0 )) s"

python3 scripts/device_data.py .devrun/train_ids.txt /tmp/dev "$SYNTH_S" "$W" \
  | tee -a "$OUT/device.txt" || exit 6
echo "data done at $(( $(date +%s) - T0 )) s" | tee -a "$OUT/device.txt"
CHUNK=$(python3 -c "print(max(0.5, ($(left) - 60) / 60))")   # ~1 min for the box-frame cache
CMD=(train sdf --data /tmp/dev/prepared --preset "$PRESET" --out /tmp/dev/sdf --seed 0
     --threads "$W" --steps "$STEPS" --batch-size "$BATCH" --no-progress --device "$DEV"
     --chunk-minutes "$CHUNK" --resume)
echo "artformer ${CMD[*]}" | tee -a "$OUT/device.txt"
timeout --signal=TERM "$(left)" python3 -c "$PYMAIN" "${CMD[@]}" 2>&1 | tail -40 \
  | tee -a "$OUT/device.txt"
echo "train stopped at $(( $(date +%s) - T0 )) s" | tee -a "$OUT/device.txt"
cp /tmp/dev/sdf/log.jsonl "$OUT/sdf_log.jsonl" 2>/dev/null
cp /tmp/dev/prepared/manifest.json "$OUT/manifest.json" 2>/dev/null
[ -f /tmp/dev/sdf/ckpt.pt ] && split -b 15M -d /tmp/dev/sdf/ckpt.pt "$OUT/sdf_ckpt.part"
ls -la "$OUT"
