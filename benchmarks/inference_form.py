"""The inference form (``models.inference``) against the network as trained, eager torch, same run: frames/s at
each batch size for the trained form, the batch norms folded alone (the per-group layers), and the stacked
groups (what the inference form runs below ``BATCH_PER_GROUP`` windows). The three are interleaved, each timed
as the median of its repetitions, so the machine's drift touches them alike.

    .venv/bin/python benchmarks/inference_form.py [--model ray3d] [--batches 1 8 32 128 512 1024] [--threads 2]
"""
import argparse
import copy
import time

import torch

from ray3d.models import PRESETS, LiftingNetwork, TensorBatch
from ray3d.models.inference import BATCH_PER_GROUP, fold_batch_norms, inference_network


def seconds(model, batch, repeats) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        model(batch)
        times.append(time.perf_counter() - start)
    return sorted(times)[len(times) // 2]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="ray3d")
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 8, 32, 128, 512, 1024])
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    trained = LiftingNetwork(PRESETS[args.model]).eval()
    folded = copy.deepcopy(trained)
    fold_batch_norms(folded)
    stacked = inference_network(trained)
    for branch in (stacked.pose_net, stacked.trajectory_net):
        branch.batch_per_group = float("inf")  # the stacked path at every batch size, for this comparison
    forms = {"as trained": trained, "folded": folded, "stacked": stacked}

    print(f"{args.model}, {args.threads} threads; frames/s (the inference form takes 'stacked' below "
          f"{BATCH_PER_GROUP} windows, 'folded' from there)")
    print(f"{'batch':>6}" + "".join(f"{name:>13}" for name in forms) + f"{'best / trained':>16}")
    with torch.no_grad():
        for size in args.batches:
            batch = TensorBatch.example(trained.receptive_field, trained.skeleton.num_joints, size)
            repeats = max(5, 400 // size)
            for model in forms.values():
                seconds(model, batch, 3)  # warm-up
            rates = {name: [] for name in forms}
            for _ in range(3):
                for name, model in forms.items():
                    rates[name].append(size / seconds(model, batch, repeats))
            medians = {name: sorted(r)[1] for name, r in rates.items()}
            print(f"{size:>6}" + "".join(f"{medians[n]:>13,.0f}" for n in forms)
                  + f"{max(medians['folded'], medians['stacked']) / medians['as trained']:>15.2f}x")


if __name__ == "__main__":
    main()
