"""A soak of ``ray3d live``: a video looped at its own rate for a long time (30 minutes by default), the page
served and read by a client as a browser would. Every 10 s it notes the process's resident memory and the
live path's queues; at the end it checks that every event was written (the log's lines against the runner's
count, and the store's rows: OUT/site.db, SQLite, as ``ray3d live`` writes it) and reports the memory after the first
minute, its largest rise after that, and the frames dropped.

    python benchmarks/history/live_soak.py ../shared/data/real-video/vtest.avi \\
        --camera ../shared/data/real-video/vtest_camera.json --site benchmarks/vtest_site.json \\
        --minutes 30 --out DIR
"""

from __future__ import annotations

import argparse
import json
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np

from ray3d.io.camera_files import read_camera
from ray3d.jobs import CameraChoice, Job
from ray3d.jobs.live import live_job, local_inputs
from ray3d.live.runner import LiveOptions
from ray3d.live.source import FrameSource, SourceGroup, _opened
from ray3d.site.files import read_site
from ray3d.store import read_record
from ray3d.video import make_detector


def _looped(path: str, seconds: float, fps: float):
    """The video's frames again and again (RGB) for ``seconds`` of its time."""
    import cv2

    count = 0
    while count < seconds * fps:
        capture, frame, _ = _opened(path)
        while frame is not None and count < seconds * fps:
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
            count += 1
            ok, frame = capture.read()
            frame = frame if ok else None
        capture.release()


def _resident_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _read_feed(url: str, stop: threading.Event, counter: list) -> None:
    with urllib.request.urlopen(url + "stream", timeout=60) as feed:
        for line in feed:
            if stop.is_set():
                return
            counter[0] += line.startswith(b"data: ")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("video")
    parser.add_argument("--camera", required=True)
    parser.add_argument("--site", type=Path)
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    camera = read_camera(args.camera)
    _, _, fps = _opened(args.video)
    source = FrameSource(_looped(args.video, 60 * args.minutes, fps), fps, f"{args.video} looped", paced=True)
    detector = make_detector("combined", camera, live=True)
    detector.prepare([])
    samples, stop, snapshots = [], threading.Event(), [0]
    start = time.monotonic()

    def sample() -> None:
        while not stop.wait(10.0):
            samples.append({"t_s": round(time.monotonic() - start, 1), "rss_mb": round(_resident_mb(), 1),
                            "read": source.read, "dropped": source.dropped})
            print(json.dumps(samples[-1]), flush=True)

    def started(url: str) -> None:
        threading.Thread(target=_read_feed, args=(url, stop, snapshots), daemon=True).start()

    threading.Thread(target=sample, daemon=True).start()
    run = live_job(Job((source.name,), (CameraChoice(args.camera),)), args.out, LiveOptions(port=0),
                   lambda job, recorder: local_inputs(job, SourceGroup([source]), [camera], [detector],
                                                      recorder.id_prefix),
                   site=read_site(args.site) if args.site else None, store=args.out / "site.db", command="live_soak",
                   started=started)
    summary, recorder = run.summary, run.recorder
    stop.set()
    written = len((args.out / "events.jsonl").read_text().splitlines())
    stored = len(read_record(args.out / "site.db").events)
    after_minute = [s["rss_mb"] for s in samples if s["t_s"] >= 60]
    print(json.dumps({
        "ending": summary.why, "minutes": round((time.monotonic() - start) / 60, 1), "read": summary.read,
        "processed": summary.processed, "dropped_percent": round(100 * summary.dropped / max(summary.read, 1), 2),
        "latency_ms": {"median": float(np.median(summary.latency_ms)),
                       "p99": float(np.percentile(summary.latency_ms, 99))},
        "events": summary.events, "events_written": written, "events_in_the_store": stored,
        "store_rows_lost": recorder.lost, "store_written": recorder.written, "tracks": summary.tracks,
        "left_out": len(summary.left_out), "snapshots_read_by_the_page_client": snapshots[0],
        "rss_mb_at_1_min": after_minute[0] if after_minute else None,
        "rss_mb_largest_rise_after_1_min": round(max(after_minute) - after_minute[0], 1) if after_minute else None,
        "rss_mb_last": after_minute[-1] if after_minute else None}, indent=1))


if __name__ == "__main__":
    main()
