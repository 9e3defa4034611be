"""The ablation, baselines, temporal-window and cross-data tables from the JSON files of benchmarks/paper_tables.sh
(named MODEL@CAMERAS[@OPTIONS].json).

    .venv/bin/python benchmarks/paper_tables.py results/tables
"""

import json
import sys
from pathlib import Path


def cell(results, key, field="mrpe_mm"):
    value = results.get(key, {}).get(field)
    return "-" if value is None else f"{value:.1f}"


def table(results, title, rows):
    print(f"\n{title}\n")
    print("| model | what it adds | h36m Abs-MPJPE | h36m MRPE | extrinsic-test Abs-MPJPE | extrinsic-test MRPE |")
    print("|---|---|---|---|---|---|")
    for name, what in rows:
        if f"{name}@h36m" in results:
            print(f"| {name} | {what} | {cell(results, name + '@h36m', 'abs_mpjpe_mm')} | "
                  f"{cell(results, name + '@h36m')} | {cell(results, name + '@extrinsic-test', 'abs_mpjpe_mm')} | "
                  f"{cell(results, name + '@extrinsic-test')} |")


def main() -> None:
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "results/tables")
    results = {path.stem: json.loads(path.read_text()) for path in sorted(folder.glob("*.json"))}

    table(results, "Ablation (mm; every model trained 10 x 100 batches of 1024):", [
        ("rie", "RIE on pixels normalised by the image width, root in the camera frame"),
        ("rie-decoupled", "+ intrinsic decoupling: camera-frame rays instead of pixels"),
        ("ray3d-no-ce", "+ normalisation: rays and targets in the NCS (pitch removed)"),
        ("ray3d-xyz", "+ camera embedding of (height, pitch): the paper's Ray3D"),
        ("ray3d", "+ root as depth along its ray, ground-plane features (ours)"),
    ])
    table(results, "Other baselines (mm; same budget):", [
        ("poselifter", "PoseLifter-style: one frame, pixels minus the principal point, depth x focal length"),
        ("poseformer", "PoseFormer-style: attention over each frame's joints, then over 9 frames; pixels"),
    ])
    table(results, "Temporal window (mm; same budget):", [
        ("ray3d-1frame", "1 frame"), ("ray3d", "9 frames, centred"), ("ray3d-causal", "9 frames, past only (live)"),
    ])
    print("\nCross-data, 14-joint layout, extrinsic-test cameras, test performers of each dataset "
          "(mm, Abs-MPJPE / MRPE):\n")
    print("| model, trained on | tested on CMU (cmu_02, cmu_07) | tested on HDM05 (hdm05_mm) |")
    print("|---|---|---|")
    for name, data in (("ray3d-cmu", "Ray3D, CMU only"), ("ray3d-hdm05", "Ray3D, HDM05 only"),
                       ("ray3d", "Ray3D, CMU + HDM05"), ("rie-cmu", "RIE (pixels), CMU only")):
        cells = [f"{cell(results, f'{name}@extrinsic-test@--datasets{d}--jointsh36m14', 'abs_mpjpe_mm')} / "
                 f"{cell(results, f'{name}@extrinsic-test@--datasets{d}--jointsh36m14')}" for d in ("cmu", "hdm05")]
        print(f"| {data} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
