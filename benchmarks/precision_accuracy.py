"""What reduced precision costs every shipped model: Abs-MPJPE and MPJPE on the test performers (GT 2D, every 4th
frame) through the issue's camera sets, fp32 against bf16 and int8 (``models.precision``) on the same clips; a
markdown table. ``ray3d evaluate --precision P`` gives the same change for one model and set.

    .venv/bin/python benchmarks/precision_accuracy.py [--models ray3d ray3d-real ...] [--cameras h36m far-test]
"""

from __future__ import annotations

import argparse

from ray3d.checkpoints import shipped_models
from ray3d.evaluate import evaluate, evaluation_cameras, evaluation_motion
from ray3d.models.precision import PRECISIONS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", nargs="+", default=sorted(shipped_models()))
    parser.add_argument("--cameras", nargs="+", default=["h36m", "far-test"])
    parser.add_argument("--frame-stride", type=int, default=4)
    args = parser.parse_args()
    clips, _ = evaluation_motion()
    reduced = [p for p in PRECISIONS if p != "fp32"]
    print("| model | cameras | fp32 Abs-MPJPE / MPJPE mm | "
          + " | ".join(f"{p} change (Abs / MPJPE) mm" for p in reduced) + " |")
    print("|---|---|---|" + "---|" * len(reduced))
    for model in args.models:
        for spec in args.cameras:
            cameras = evaluation_cameras(spec)
            result = {p: evaluate(model, clips, cameras, frame_stride=args.frame_stride, precision=p)
                      for p in PRECISIONS}
            full = result["fp32"]
            changes = " | ".join(f"{result[p]['abs_mpjpe_mm'] - full['abs_mpjpe_mm']:+.2f} / "
                                 f"{result[p]['mpjpe_mm'] - full['mpjpe_mm']:+.2f}" for p in reduced)
            print(f"| {model} | {spec} | {full['abs_mpjpe_mm']:.1f} / {full['mpjpe_mm']:.1f} | {changes} |", flush=True)


if __name__ == "__main__":
    main()
