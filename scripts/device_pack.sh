#!/usr/bin/env bash
# Pack what scripts/device_sdf.sh needs on a GPU machine whose image has torch, numpy, scipy and
# scikit-image but not the geometry packages: .devrun/devsite.tar.xz (cp312 x86-64 builds of
# the pinned libigl, manifold3d, mujoco, trimesh, vhacdx, yourdfpy and mujoco's glfw/etils,
# stripped of headers, static libraries and unused extension modules: ~6 MB) and
# .devrun/train_ids.txt (the train split of the full 10,000-object dataset).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source scripts/env.sh
N_OBJECTS=${N_OBJECTS:-10000}
tmp=$(mktemp -d)
plat=(--only-binary=:all: --python-version 3.12 --implementation cp
      --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64
      --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64)
pins=$(grep -E '^(libigl|manifold3d|mujoco|trimesh|vhacdx|yourdfpy)==' requirements.txt)
# shellcheck disable=SC2086
python -m pip download -q --no-deps "${plat[@]}" -d "$tmp/whl" $pins glfw etils
python -m pip install -q --no-deps --no-compile "${plat[@]}" --target "$tmp/devsite" \
  "$tmp"/whl/*.whl
rm -rf "$tmp"/devsite/{include,share,lib64} "$tmp"/devsite/igl/{embree,copyleft} \
       "$tmp"/devsite/mujoco/{include,plugin}
find "$tmp/devsite" -name '*.so*' -exec strip --strip-unneeded {} \; 2>/dev/null || true
mkdir -p .devrun
tar cJf .devrun/devsite.tar.xz -C "$tmp" devsite
python - "$N_OBJECTS" <<'EOF'
import sys
from model.data.preprocess import assign_splits
ids = [f"{i:06d}" for i in range(int(sys.argv[1]))]
split = assign_splits(ids, 0)
train = [str(int(i)) for i in ids if split[i] == "train"]
open(".devrun/train_ids.txt", "w").write("\n".join(train))
EOF
rm -rf "$tmp"
ls -la .devrun
