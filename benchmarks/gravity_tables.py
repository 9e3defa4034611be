"""The gravity-aligned NCS ablation of docs/RESULTS.md: ``ray3d`` trained on cameras rolled up to 8 deg, with
the roll kept in the NCS (the paper) and undone (``remove_roll``), at equal budget (benchmarks/train_tables.sh
ray3d-rolled ray3d-gravity); MRPE by roll bucket on the Human3.6M cameras (their real rolls) and on the
extrinsic-test cameras rolled about their optical axes by -8 to +8 deg. Test performers, GT 2D, every 8th frame.

    python benchmarks/gravity_tables.py [RUNS_DIR] [OUT_DIR]
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from ray3d.data.virtual_cameras import grid
from ray3d.evaluate import evaluate, evaluation_motion
from ray3d.io.camera_files import save_cameras

MODELS = {"roll kept (paper NCS)": "ray3d-rolled", "roll undone (gravity-aligned NCS)": "ray3d-gravity"}
BUCKETS_DEG = ((0.0, 2.0), (2.0, 5.0), (5.0, 8.0))
MAX_ROLL_DEG = 8.0


def rolled(cameras, seed: int = 0):
    """Each camera turned about its optical axis (its centre kept) by a roll spread evenly over +-8 deg."""
    rolls = np.random.default_rng(seed).permutation(np.linspace(-MAX_ROLL_DEG, MAX_ROLL_DEG, len(cameras)))
    out = []
    for camera, roll in zip(cameras, np.radians(rolls)):
        turn = np.array([[np.cos(roll), -np.sin(roll), 0.0], [np.sin(roll), np.cos(roll), 0.0], [0.0, 0.0, 1.0]])
        R = turn @ camera.R
        out.append(dataclasses.replace(camera, R=R, t=-R @ camera.center,
                                       name=f"{camera.name}@roll{np.degrees(roll):+.1f}"))
    return out


def bucketed(result: dict, cameras) -> list[tuple[float, int]]:
    """(MRPE mm, frames) per roll bucket, frame-weighted over the cameras in it."""
    roll = {c.name: abs(np.degrees(c.roll)) for c in cameras}
    rows = []
    for low, high in BUCKETS_DEG:
        parts = [(v["mrpe_mm"], v["frames"]) for name, v in result["per_camera"].items() if low <= roll[name] < high
                 or (high == BUCKETS_DEG[-1][1] and roll[name] >= high)]
        frames = sum(f for _, f in parts)
        rows.append((sum(m * f for m, f in parts) / frames if frames else float("nan"), frames))
    return rows


def main(runs: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    motion, _ = evaluation_motion()
    sets = {"h36m": grid("h36m"), "extrinsic-test rolled +-8 deg": rolled(grid("extrinsic-test"))}
    save_cameras(out / "extrinsic-test-rolled.json", sets["extrinsic-test rolled +-8 deg"], overwrite=True)
    print("| model | cameras | MRPE roll 0-2 deg | MRPE 2-5 deg | MRPE 5-8 deg | all: MRPE / Abs-MPJPE |")
    print("|---|---|---|---|---|---|")
    for label, run in MODELS.items():
        for set_name, cameras in sets.items():
            file = out / f"{run}@{set_name.split()[0]}{'-rolled' if 'rolled' in set_name else ''}.json"
            if file.exists():
                result = json.loads(file.read_text())
            else:
                result = evaluate(str(runs / run / "best.safetensors"), motion, cameras, frame_stride=8)
                file.write_text(json.dumps(result, indent=1))
            cells = " | ".join(f"{m:.1f} ({f:,} frames)" for m, f in bucketed(result, cameras))
            print(f"| {label} | {set_name} | {cells} | {result['mrpe_mm']:.1f} / {result['abs_mpjpe_mm']:.1f} |",
                  flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "runs/tables"),
         Path(sys.argv[2] if len(sys.argv) > 2 else "results/tables"))
