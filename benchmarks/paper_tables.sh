#!/usr/bin/env bash
# Evaluate the models of benchmarks/train_tables.sh (test performers, GT 2D, every 8th frame) and print the
# ablation, 1-frame vs 9-frame, causal vs centred and cross-data tables of docs/RESULTS.md (unfinished runs are
# left out).
#   bash benchmarks/paper_tables.sh [RUNS_DIR] [OUT_DIR]
set -euo pipefail
runs=${1:-runs/tables}
out=${2:-results/tables}
mkdir -p "$out"
finished() {  # whether the run NAME has trained all its epochs
  .venv/bin/python -c "import json, sys; d = json.load(open(sys.argv[1])); sys.exit(d['epoch'] != d['train_config']['epochs'])" \
    "$runs/$1/last.json" 2> /dev/null
}
evaluate() {  # NAME CAMERAS [extra evaluate arguments]; skips what exists
  local name=$1 cameras=$2; shift 2
  local options="$*"
  local file="$out/$name@$cameras${options:+@${options// /}}.json"
  [ -f "$file" ] || .venv/bin/ray3d evaluate --checkpoint "$runs/$name/best.safetensors" --cameras "$cameras" \
    --frame-stride 8 --json "$file" "$@" > /dev/null
}
for name in rie rie-decoupled ray3d-no-ce ray3d-xyz ray3d ray3d-1frame ray3d-causal poselifter poseformer; do
  finished "$name" || continue
  for cameras in h36m extrinsic-test; do evaluate "$name" "$cameras"; done
done
for name in ray3d ray3d-cmu ray3d-hdm05 rie-cmu; do
  finished "$name" || continue
  for dataset in cmu hdm05; do evaluate "$name" extrinsic-test --datasets "$dataset" --joints h36m14; done
done
.venv/bin/python benchmarks/paper_tables.py "$out"
