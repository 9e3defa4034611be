#!/usr/bin/env bash
# The bars of "Right on real footage": each model on the h36m, extrinsic-test, far-test and low-test camera
# sets (test performers, GT 2D, every 8th frame, i.e. 7.5 fps tracks; intrinsic-test every 16th), without and with the track-level
# refinement, then the table (MRPE as a share of the camera-person distance for far and low cameras).
#   bash benchmarks/evaluate_real.sh OUT_DIR MODEL [MODEL ...]
set -euo pipefail
out=$1; shift
mkdir -p "$out"
for model in "$@"; do
  label=$(basename "$model" .safetensors)
  for cameras in h36m extrinsic-test far-test low-test intrinsic-test; do
    stride=8; [ "$cameras" = intrinsic-test ] && stride=16
    for refine in "" --refine; do
      .venv/bin/ray3d evaluate --checkpoint "$model" --cameras "$cameras" --frame-stride "$stride" $refine \
        --json "$out/$label${refine:+-refined}@$cameras.json" --force > /dev/null
    done
  done
done
.venv/bin/python benchmarks/summarise_real.py "$out"
