#!/usr/bin/env bash
# Train the models behind the ablation, 1-frame vs 9-frame, causal, cross-data, PoseFormer and gravity tables of docs/RESULTS.md, all
# at one reduced budget (10 epochs x 100 batches of 1024) so they compare like for like; an interrupted run is resumed
# and a finished one left as it is.
#   bash benchmarks/train_tables.sh [RUNS_DIR] [NAME ...]
set -euo pipefail
runs=${1:-runs/tables}
shift || true
budget=(--epochs 10 --batches-per-epoch 100 --threads 1 --quiet)
declare -A how=(
  [rie]="--config configs/ray3d.json --preset rie"
  [rie-decoupled]="--config configs/ray3d.json --preset rie-decoupled"
  [ray3d-no-ce]="--config configs/ray3d.json --preset ray3d-no-ce"
  [ray3d-xyz]="--config configs/ray3d.json --preset ray3d-xyz"
  [ray3d]="--config configs/ray3d.json"
  [ray3d-1frame]="--config configs/ray3d-1frame.json"
  [ray3d-causal]="--config configs/ray3d-causal.json"
  [ray3d-cmu]="--config configs/ray3d-cmu.json"
  [ray3d-hdm05]="--config configs/ray3d-hdm05.json"
  [poselifter]="--config configs/ray3d.json --preset poselifter"
  [rie-cmu]="--config configs/ray3d-cmu.json --preset rie"
  [poseformer]="--config configs/ray3d.json --preset poseformer"
  [ray3d-rolled]="--config configs/ray3d-rolled.json"
  [ray3d-gravity]="--config configs/ray3d-gravity.json"
)
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(rie rie-decoupled ray3d-no-ce ray3d-xyz ray3d ray3d-1frame ray3d-causal ray3d-cmu ray3d-hdm05 poselifter rie-cmu poseformer
  ray3d-rolled ray3d-gravity)
for name in "${names[@]}"; do
  start=$(date +%s)
  resume=(); [ -f "$runs/$name/last.json" ] && resume=(--resume)
  .venv/bin/ray3d train ${how[$name]} "${budget[@]}" --out "$runs/$name" "${resume[@]}"
  echo "$name: trained in $(( $(date +%s) - start )) s"
done
