#!/usr/bin/env bash
# Test-performer numbers of every shipped model (and RFRH) on the h36m, extrinsic-test and intrinsic-test camera
# sets, GT 2D, every 4th frame (windows still use every frame), then the markdown summary.
#   bash benchmarks/evaluate_shipped.sh [OUT_DIR]
set -euo pipefail
out=${1:-results}
mkdir -p "$out"
for model in ray3d ray3d-wide ray3d-causal videopose3d rie poseformer rfrh; do
  for cameras in h36m extrinsic-test intrinsic-test; do
    .venv/bin/ray3d evaluate --checkpoint "$model" --cameras "$cameras" --frame-stride 4 \
      --json "$out/$model@$cameras.json" --force > /dev/null
  done
done
.venv/bin/python benchmarks/summarise.py "$out"
