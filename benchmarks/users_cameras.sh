#!/usr/bin/env bash
# "Never worse than the guess" and "Train for the cameras people use": each model on the low, level cameras
# (bench level), the real near views against their truth (bench real-near, the video extra's environment), the
# mocap camera sets with GT 2D refined (test performers, every 8th frame), and vtest.avi's physical checks from one
# set of detections. Tables: benchmarks/summarise_real.py OUT and the .md files.
#   bash benchmarks/users_cameras.sh OUT VIDEO_ENV_BIN VTEST_KEYPOINTS MODEL [MODEL ...]
set -euo pipefail
out=$1; video_bin=$2; vtest_keypoints=$3; shift 3
mkdir -p "$out"
for model in "$@"; do
  label=$(basename "$model" .safetensors)
  [[ "$model" == */* ]] && label="$(basename "$(dirname "$model")")-$label"  # runs/A/best and runs/B/best differ
  .venv/bin/ray3d bench level --checkpoint "$model" --out "$out/level-$label" > /dev/null
  "$video_bin/ray3d" bench real-near --checkpoint "$model" --out "$out/near-$label" > /dev/null 2>&1
  .venv/bin/ray3d bench real-video --keypoints "$vtest_keypoints" --camera ../shared/data/real-video/vtest_camera.json \
    --checkpoint "$model" --smooth-3d savgol --pairs 24 --out "$out/vtest-$label" > /dev/null
  for cameras in h36m far-test low-test near-test; do
    .venv/bin/ray3d evaluate --checkpoint "$model" --cameras "$cameras" --frame-stride 8 --refine \
      --json "$out/$label-refined@$cameras.json" --force > /dev/null
  done
done
.venv/bin/python benchmarks/summarise_real.py "$out"
