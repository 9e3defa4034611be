"""`ray3d batch` on 1 and on 2 local Ray workers: 20 keypoint files (test-performer mocap clips seen by
extrinsic-test cameras, GT 2D, each played forwards and backwards to ``--frames`` frames so that a file is minutes
long, as a camera's footage is), the same manifest and outputs; wall time of the job, with and without starting
Ray, and the ratio; with ``--repeats N`` the pair is run N times, alternating, and the median ratio is the figure
(this machine's timings vary by 5-10 % from run to run). The outputs of the runs are compared byte for byte.

    python benchmarks/batch_scaling.py [OUT_DIR] [--files 20] [--frames 6000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

from ray3d.batch import run
from ray3d.data.motion import load_shipped
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.io.camera_files import save_cameras


def make_inputs(folder: Path, count: int, frames: int) -> Path:
    """``count`` keypoint files of the longest test clips, each through its own camera, and their manifest."""
    folder.mkdir(parents=True, exist_ok=True)
    motion = load_shipped(split="test")
    clips = sorted((centre_clip(motion.clip(i).astype(np.float64)) for i in range(motion.num_clips)),
                   key=len, reverse=True)
    cameras = grid("extrinsic-test")
    rows, k = ["input,camera,fps"], 0
    for clip in clips:
        camera = next(c for c in cameras[k % len(cameras):] + cameras if c.sees(clip))
        k += 1
        clip = np.concatenate([clip, clip[::-1]] * (frames // (2 * len(clip)) + 1))[:frames]
        save_cameras(folder / f"camera{len(rows)}.json", [camera], overwrite=True)
        np.savez(folder / f"take{len(rows)}.npz", keypoints=camera.project(clip), fps=60.0)
        rows.append(f"take{len(rows)}.npz,camera{len(rows)}.json,60")
        if len(rows) > count:
            break
    (folder / "manifest.csv").write_text("\n".join(rows) + "\n")
    return folder / "manifest.csv"


def timed(manifest: Path, out: Path, workers: int) -> dict:
    import ray

    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    ready = time.perf_counter()
    report = run(manifest, out, workers=workers, progress=False)
    finished = time.perf_counter()
    ray.shutdown()
    assert not report.failed, report.failed
    return {"workers": workers, "seconds_with_ray_start": finished - started,
            "seconds_after_ray_start": finished - ready, "frames": sum(r.frames for r in report.reports)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", nargs="?", type=Path, default=Path("results/batch-scaling"))
    parser.add_argument("--files", type=int, default=20)
    parser.add_argument("--frames", type=int, default=6000, help="frames per file (60 fps)")
    parser.add_argument("--repeats", type=int, default=1, help="pairs of runs; the median ratio is reported")
    args = parser.parse_args()
    manifest = make_inputs(args.out / "inputs", args.files, args.frames)
    runs = []
    for _ in range(args.repeats):
        one = timed(manifest, args.out / "one-worker", 1)
        two = timed(manifest, args.out / "two-workers", 2)
        same = all((args.out / "one-worker" / p.parent.name / "world.json").read_bytes() == p.read_bytes()
                   for p in (args.out / "two-workers").glob("*/world.json"))
        runs.append({"one": one, "two": two, "identical_outputs": same,
                     "speed_up_with_ray_start": one["seconds_with_ray_start"] / two["seconds_with_ray_start"],
                     "speed_up_after_ray_start": one["seconds_after_ray_start"] / two["seconds_after_ray_start"]})
    result = {"runs": runs, "identical_outputs": all(r["identical_outputs"] for r in runs),
              **{f"median_{key}": float(np.median([r[key] for r in runs]))
                 for key in ("speed_up_with_ray_start", "speed_up_after_ray_start")}}
    (args.out / "batch-scaling.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
