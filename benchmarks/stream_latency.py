"""Live-mode latency: the median wall time of one ``LiftStream.push`` (keypoints in, world joints out) with the
shipped model through each backend, and of its first step alone, the frame's pixels to NCS rays (the lens
inverted by Newton's method), over the bundled demo clip seen by a Human3.6M camera (which has lens distortion).
Run it against another tree for an A/B: ``PYTHONPATH=<tree>/src python benchmarks/stream_latency.py``.

    .venv/bin/python benchmarks/stream_latency.py [--model ray3d] [--backends torch torchscript] [--threads 2]
"""
import argparse
import time

import numpy as np
import torch

from ray3d import cameras
from ray3d.bench.speed import stream_ms_per_frame
from ray3d.demo import demo_clip
from ray3d.jobs import load_lifter
from ray3d.models import backends

RUNNERS = {"torch": lambda model: model,  # the network itself; the others trace it
           "torchscript": lambda model: backends.TorchScriptLiftingModel(model, 1000.0),
           "onnx": lambda model: backends.OnnxLiftingModel(model, 1000.0)}


def median_ms(call, items) -> float:
    times = []
    for item in items:
        start = time.perf_counter()
        call(item)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times[20:]))  # the first 20: warm-up


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="ray3d")
    parser.add_argument("--backends", nargs="+", choices=list(RUNNERS), default=["torch", "torchscript"])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--frames", type=int, default=300)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    camera = cameras.h36m("S9", "54138969")
    pixels = camera.project(demo_clip()[:args.frames])

    print(f"pixels -> rays, one frame: {median_ms(camera.pixels_to_rays, pixels):.3f} ms")
    model = load_lifter(args.model).model
    for backend in args.backends:
        print(f"{args.model} {backend}: push {stream_ms_per_frame(RUNNERS[backend](model), args.frames):.2f} ms")


if __name__ == "__main__":
    main()
