"""Where a training step's time goes, and its rate: for a preset at batch 1024, the step alone (one batch reused)
and the loop (each batch drawn by the sample generator, as ``ray3d train`` does), medians after 2 warm-up
steps; ``--profile`` adds torch.profiler's table over 5 steps, ``--dropout-masks`` times torch's Bernoulli
sampler against the random bits ``models.blocks.Dropout`` draws. Runs with whichever ray3d is importable, so an
older tree can be measured beside this one:

    PYTHONPATH=<tree>/src python benchmarks/training_step.py ray3d [--repeats 10] [--profile] [--dropout-masks]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

import ray3d.train as training
from ray3d.models.network import LiftingNetwork, lifting_loss
from ray3d.models.presets import preset


def median_seconds(function, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("preset")
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--dropout-masks", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(2)
    config = training.TrainConfig(model=preset(args.preset), batch_size=args.batch)
    torch.manual_seed(0)
    model = LiftingNetwork(config.model).train()
    optimizer = (training.make_optimizer(model, config) if hasattr(training, "make_optimizer")  # older trees
                 else torch.optim.Adam(model.parameters(), lr=config.learning_rate, amsgrad=True))
    generator = training.sample_generator(config, "train", config.samples, 0)
    fixed = generator.batch(args.batch)

    def step(batch) -> None:
        tensors = training.batch_tensors(batch)
        target_pose, target_root = model.targets(tensors, torch.from_numpy(batch.pose), torch.from_numpy(batch.root))
        pose, root = model(tensors)
        loss = lifting_loss(pose, root, target_pose, target_root)[0]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    for _ in range(2):
        step(fixed)
    result = {"ray3d": training.__file__, "preset": args.preset,
              "step_samples_per_s": args.batch / median_seconds(lambda: step(fixed), args.repeats),
              "loop_samples_per_s": args.batch / median_seconds(lambda: step(generator.batch(args.batch)),
                                                                args.repeats)}
    if args.dropout_masks:
        x = torch.randn(3 * args.batch, 640)
        words = (x.numel() + 3) // 4
        result["bernoulli_ms"] = 1e3 * median_seconds(lambda: torch.empty_like(x).bernoulli_(0.9), 20)
        result["random_bits_ms"] = 1e3 * median_seconds(
            lambda: torch.randint(-2**63, 2**63 - 1, (words,), dtype=torch.int64).view(torch.int16) >= -26214, 20)
    print(json.dumps(result))
    if args.profile:
        from torch.profiler import profile

        with profile() as profiler:
            for _ in range(5):
                step(fixed)
        print(profiler.key_averages().table(sort_by="self_cpu_time_total", row_limit=15))


if __name__ == "__main__":
    main()
