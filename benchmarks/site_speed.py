"""``ray3d site`` on a long world file: TRACKS people walking for HOURS at FPS, as the command runs it (the site
file of two zones and two lines, every table and plot written).

    .venv/bin/python benchmarks/site_speed.py --tracks 20 --hours 1 --fps 10
"""

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from ray3d import cameras
from ray3d.cli import main as cli
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, write_world


def long_world(tracks: int, seconds: float, fps: float, seed: int = 0) -> World:
    """People walking a random smooth path around a 20 m square, the demo clip's pose looped."""
    rng = np.random.default_rng(seed)
    frames = int(seconds * fps)
    pose = demo_clip()
    pose = pose - np.concatenate([pose[:, :1, :2], np.zeros((len(pose), 1, 1))], axis=-1)
    results = {}
    for track in range(tracks):
        angle = np.cumsum(rng.normal(0, 0.05, frames))
        steps = 1.2 / fps * np.column_stack([np.cos(angle), np.sin(angle)])
        path = np.cumsum(steps, axis=0)
        path = 10 - np.abs((path % 40) - 20)  # folded back into a 20 m square
        joints = pose[np.arange(frames) % len(pose)] + np.column_stack([path, np.zeros(frames)])[:, None]
        results[str(track)] = LiftResult(joints, np.zeros((frames, 17), bool), fps, np.arange(frames),
                                         refinement={"stature_m": 1.7, "stature_interval_m": [1.6, 1.8]},
                                         position_sd=np.full((frames, 2), 0.1))
    return World(results, cameras.h36m("S9", "54138969"), "ray3d")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tracks", type=int, default=20)
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--fps", type=float, default=10.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        world = write_world(folder / "world.npz", long_world(args.tracks, args.hours * 3600, args.fps))
        site = folder / "site.json"
        site.write_text(json.dumps({
            "zones": [{"name": "a", "polygon": [[-10, -10], [0, -10], [0, 0], [-10, 0]], "max_occupancy": 5},
                      {"name": "b", "polygon": [[0, 0], [10, 0], [10, 10], [0, 10]], "max_dwell_s": 60}],
            "lines": [{"name": "x", "start": [0, -10], "end": [0, 10]},
                      {"name": "y", "start": [-10, 0], "end": [10, 0]}]}))
        start = time.perf_counter()
        code = cli(["site", str(world), "--site", str(site), "--out", str(folder / "report")])
        print(f"{args.tracks} tracks x {args.hours:g} h at {args.fps:g} fps: exit {code}, "
              f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
