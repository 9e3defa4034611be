"""Time of `ray3d viz`'s renderer per image: `render_frames` (camera view, world, floor plan) on two tracks of
the bundled demo clip; the first image (figure and layout) reported apart.

    python benchmarks/render_speed.py [--frames 20]
"""

import argparse
import time

import numpy as np

from ray3d import cameras
from ray3d.demo import DEMO_CAMERA, demo_clip
from ray3d.io.world import LiftResult
from ray3d.viz.animation import render_frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    n = parser.parse_args().frames
    camera = cameras.h36m(*DEMO_CAMERA)
    clip = demo_clip()[:n]
    people = {"1": LiftResult(clip, np.zeros((n, 17), bool), 30.0, np.arange(n)),
              "2": LiftResult(clip + [1.0, 0.0, 0.0], np.zeros((n, 17), bool), 30.0, np.arange(n))}
    started = time.perf_counter()
    for count, image in enumerate(render_frames(people, camera, fps=30.0), start=1):
        if count == 1:
            first = time.perf_counter()
    per_image = (time.perf_counter() - first) / (count - 1)
    print(f"{count} images of {image.size[0]}x{image.size[1]}: first {first - started:.2f} s, then "
          f"{1e3 * per_image:.0f} ms per image")


if __name__ == "__main__":
    main()
