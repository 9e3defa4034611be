"""How far two runs of ``ray3d bench speed`` agree: for every figure both JSON files have (each form's batched
rate, latency, speed-up over fp32 and fraction of its bound; training rates; live push), the larger over the smaller.

    python benchmarks/speed_spread.py first.json second.json
"""

from __future__ import annotations

import argparse
import json

FIGURES = ("batch_frames_per_s", "latency_ms", "batch_speedup_over_fp32", "batch_fraction_of_fp32_peak",
           "latency_fraction_of_bound")
TRAINING = ("train_step_samples_per_s", "train_loop_samples_per_s", "train_step_fraction_of_bound",
            "train_loop_fraction_of_bound")


def figures(result: dict) -> dict[str, float]:
    values = {}
    for r in result["inference"]:
        values.update({f"{r['model']} {r['form']} {k}": r[k] for k in FIGURES})
    for r in result["training"]:
        values.update({f"{r['model']} {k}": r[k] for k in TRAINING if r[k] is not None})
    for r in result["streams"]:
        values.update({f"{r['model']} {k}": v for k, v in r.items() if k.startswith("stream_ms_")})
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("first")
    parser.add_argument("second")
    args = parser.parse_args()
    first, second = (figures(json.load(open(path))) for path in (args.first, args.second))
    spreads = {k: max(first[k], second[k]) / min(first[k], second[k]) for k in first if k in second}
    for name, spread in sorted(spreads.items(), key=lambda item: -item[1]):
        print(f"{spread:6.3f}  {name}: {first[name]:.4g} / {second[name]:.4g}")
    within = sum(s <= 1.15 for s in spreads.values())
    print(f"{within} of {len(spreads)} figures within 1.15x; largest {max(spreads.values()):.3f}x")


if __name__ == "__main__":
    main()
