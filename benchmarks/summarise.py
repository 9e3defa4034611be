"""Markdown tables from ``ray3d evaluate --json`` files named MODEL@CAMERAS.json in one folder.

    .venv/bin/python benchmarks/summarise.py results
"""

import json
import sys
from collections import defaultdict
from pathlib import Path


def cell(value):
    return "-" if value is None else f"{value:.1f}"


def main() -> None:
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "results")
    results = {}
    for path in sorted(folder.glob("*.json")):
        model, cameras = path.stem.split("@", 1)
        results[(model, cameras)] = json.loads(path.read_text())
    models = list(dict.fromkeys(m for m, _ in results))

    print("| model | cameras | pairs (skipped) | frames | MPJPE | P-MPJPE | Abs-MPJPE | MRPE |")
    print("|---|---|---|---|---|---|---|---|")
    for (model, cameras), r in results.items():
        print(f"| {model} | {cameras} | {r['pairs']} ({r['skipped_pairs']}) | {r['frames']:,} | "
              f"{cell(r['mpjpe_mm'])} | {cell(r['p_mpjpe_mm'])} | {cell(r['abs_mpjpe_mm'])} | {cell(r['mrpe_mm'])} |")

    if any(c == "extrinsic-test" for _, c in results):
        print("\nMRPE (mm) on the extrinsic-test pitch sweep (3 yaws, 10.5 m), by pitch:\n")
        by_pitch = {m: defaultdict(list) for m in models}
        for model in models:
            r = results.get((model, "extrinsic-test"))
            for name, values in (r or {}).get("per_camera", {}).items():
                if name.startswith("pitch:") or name.startswith("rotation:"):
                    by_pitch[model][round(values["pitch_deg"])].append(values["mrpe_mm"])
        pitches = sorted(set().union(*(b.keys() for b in by_pitch.values())))
        print("| pitch (deg) | " + " | ".join(models) + " |")
        print("|---" * (len(models) + 1) + "|")
        for pitch in pitches:
            row = [cell(sum(v) / len(v)) if (v := by_pitch[m].get(pitch)) else "-" for m in models]
            print(f"| {pitch} | " + " | ".join(row) + " |")
        sweeps = {"rotation": "yaw", "distance": "distance"}
        for prefix, label in sweeps.items():
            print(f"\nMRPE (mm) on the extrinsic-test {prefix} sweep:\n")
            print(f"| {label} | " + " | ".join(models) + " |")
            print("|---" * (len(models) + 1) + "|")
            keys = sorted({name.split(":", 1)[1] for (m, c), r in results.items() if c == "extrinsic-test"
                           for name in r["per_camera"] if name.startswith(prefix + ":")})
            for key in keys:
                row = [cell(results[(m, "extrinsic-test")]["per_camera"].get(f"{prefix}:{key}", {}).get("mrpe_mm"))
                       if (m, "extrinsic-test") in results else "-" for m in models]
                print(f"| {key} | " + " | ".join(row) + " |")

    if any(c == "intrinsic-test" for _, c in results):
        print("\nIntrinsic invariance: MRPE over the 100 intrinsic-test cameras (mm):\n")
        print("| model | mean | min | max | (max - min) / mean |")
        print("|---|---|---|---|---|")
        for model in models:
            r = results.get((model, "intrinsic-test"))
            if r:
                values = [v["mrpe_mm"] for v in r["per_camera"].values()]
                mean = sum(values) / len(values)
                print(f"| {model} | {mean:.1f} | {min(values):.1f} | {max(values):.1f} | "
                      f"{(max(values) - min(values)) / mean:.1%} |")


if __name__ == "__main__":
    main()
