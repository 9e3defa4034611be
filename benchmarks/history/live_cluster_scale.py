"""How many cameras `ray3d live --address` follows at full rate: the per-camera cost (frames/s a camera actor
sustains when its stream comes at 10 and at 25 frames/s, its memory) measured on a local Ray with 1 and 2 workers,
and the cost of the one process that joins every camera's people, finds the site's events and writes the outputs
(per camera-frame, measured on synthetic people), from which the number of cameras a cluster follows is modelled.

    python benchmarks/history/live_cluster_scale.py VIDEO --camera CAMERA.json [--seconds 40] [--out results.json]

Each row plays VIDEO at the given rate (the file at that rate, as a camera would deliver it) to as many camera
actors as the local Ray has workers (one CPU each) for ``--seconds``, and reports per camera the frames read,
processed and dropped, the sustained rate and the actor's peak memory."""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import numpy as np

from ray3d.jobs import CameraChoice, Job
from ray3d.jobs.live import open_live
from ray3d.lifting.options import VideoOptions


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def camera_rows(video: str, camera: str, workers: int, fps: float, seconds: float) -> dict:
    job = Job(tuple([video] * workers), tuple(CameraChoice(camera) for _ in range(workers)),
              video=VideoOptions(fps=fps))
    inputs = open_live(job, paced=True, address="local", workers=workers)
    followed, ray = inputs.followed, inputs.ray
    try:
        started, frames = time.monotonic(), [0] * workers
        while time.monotonic() - started < seconds:
            taken = followed.next()
            if taken is None:
                break
            frames[taken[0]] += 1
        elapsed = time.monotonic() - started
        read = [w.counts[0] for w in followed.workers]
        dropped = [w.counts[1] for w in followed.workers]
        peaks = ray.get([w.actor.__ray_call__.remote(lambda self: _peak_mb()) for w in followed.workers])
        followed.close()
        followed.finish()
    finally:
        ray.shutdown()
    return {"workers": workers, "stream_fps": fps, "seconds": round(elapsed, 1),
            "processed_fps_per_camera": [round(n / elapsed, 2) for n in frames],
            "dropped_share": [round(d / max(r, 1), 3) for d, r in zip(dropped, read)],
            "actor_peak_mb": [round(p) for p in peaks]}


def joining_cost(cameras: int, people: int = 12, frames: int = 300) -> dict:
    """Milliseconds per camera-frame the joining process spends (``LiveFusion`` and the ``SiteMonitor``), for
    ``cameras`` cameras each seeing ``people`` people walking."""
    from ray3d import cameras as shipped
    from ray3d.demo import demo_clip
    from ray3d.fusion.live import LiveFusion
    from ray3d.geometry.uncertainty import PersonNow
    from ray3d.site import Site, SiteMonitor
    from ray3d.site.places import CountingLine, Zone

    camera = shipped.h36m("S9", "54138969")
    clip = demo_clip()
    fusion = LiveFusion([camera] * cameras, 0.1)
    site = Site((Zone("z", np.array([[-5.0, -5], [5, -5], [5, 5], [-5, 5]])),),
                (CountingLine("l", np.array([0.0, -5]), np.array([0.0, 5])),))
    monitor = SiteMonitor(site, 10.0)
    started = time.perf_counter()
    for frame in range(frames):
        for view in range(cameras):
            persons = [PersonNow(str(p), clip[frame % len(clip)] + [p - people / 2, 0.1 * frame % 8 - 4, 0],
                                 np.array([0.2, 0.05]), 1.7) for p in range(people)]
            joined = fusion.update(view, frame / 10, persons)
        monitor.update(frame, {p.track: p.joints for p in joined})
    ms = 1e3 * (time.perf_counter() - started) / (frames * cameras)
    return {"cameras": cameras, "people": people, "ms_per_camera_frame": round(ms, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("video")
    parser.add_argument("--camera", required=True)
    parser.add_argument("--seconds", type=float, default=40.0)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = [camera_rows(args.video, args.camera, workers, fps, args.seconds)
            for fps in (10.0, 25.0) for workers in (1, 2)]
    joining = [joining_cost(n) for n in (1, 2, 4, 8)]
    result = {"cameras": rows, "joining": joining, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    print(json.dumps(result, indent=1))
    if args.out:
        args.out.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
