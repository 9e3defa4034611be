"""Lift one hour at 60 fps (216,000 frames) and report time and peak memory; check chunking changes nothing.

    .venv/bin/python benchmarks/lift_long_sequence.py [CHECKPOINT]
"""

import resource
import sys
import time

import numpy as np

from ray3d import cameras
from ray3d.demo import demo_clip
from ray3d.jobs import load_lifter

FRAMES = 216_000


def main() -> None:
    lifter = load_lifter(sys.argv[1] if len(sys.argv) > 1 else "ray3d")
    camera = cameras.h36m("S9", "54138969")
    clip = demo_clip()
    pixels = np.tile(camera.project(clip), (FRAMES // len(clip) + 1, 1, 1))[:FRAMES]
    start = time.perf_counter()
    result = lifter.lift(pixels, camera)
    elapsed = time.perf_counter() - start
    print(f"{len(result.joints):,} frames in {elapsed:.1f} s ({len(result.joints) / elapsed:,.0f} frames/s); "
          f"peak resident memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    head = pixels[:20_000]
    same = np.array_equal(lifter.lift(head, camera, chunk=1000).joints, lifter.lift(head, camera, chunk=8192).joints)
    print(f"chunks of 1,000 and 8,192 windows give identical results on 20,000 frames: {same}")


if __name__ == "__main__":
    main()
