"""The table of ``benchmarks/evaluate_real.sh``: per model (and refinement) and camera set, Abs-MPJPE and MRPE
(mm), the median over cameras of MRPE / camera-to-person distance, and the spread of MRPE over cameras.

    .venv/bin/python benchmarks/summarise_real.py RESULTS_DIR
"""

import json
import sys
from pathlib import Path

import numpy as np
from refine_sweep import share_of_distance


def main() -> None:
    folder = Path(sys.argv[1])
    rows = {}
    for path in sorted(folder.glob("*@*.json")):
        model, cameras = path.stem.split("@", 1)
        rows.setdefault(model, {})[cameras] = json.loads(path.read_text())
    print("| model | cameras | pairs | Abs-MPJPE | MRPE | MRPE / distance (median over cameras) | "
          "MRPE spread over cameras |")
    print("|---|---|---|---|---|---|---|")
    for model, sets in rows.items():
        for cameras, r in sets.items():
            mrpe = np.array([c["mrpe_mm"] for c in r["per_camera"].values()])
            spread = 100 * (mrpe.max() - mrpe.min()) / mrpe.mean()
            print(f"| {model} | {cameras} | {r['pairs']} | {r['abs_mpjpe_mm']:.1f} | {r['mrpe_mm']:.1f} | "
                  f"{100 * share_of_distance(r):.1f} % | {spread:.1f} % |")


if __name__ == "__main__":
    main()
