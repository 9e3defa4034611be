"""``ray3d live`` on a video played at its own rate, against the offline ``ray3d video`` of the same video.

Plays the video in real time through ``jobs.live.live_job`` (the page served, a client reading its feed as a browser
would), then reports: frames dropped, latency from a frame's arrival to its people published (the runner's own
clock) and to their arrival at the page's feed (the client's), the people the detector left for the next frame
to keep up, the people found, feet on the floor (in all of each track's frames, and in the frames its feet were
seen) and statures
in both world files, and for each live track the offline track it is (most shared frames, pelvis within 1 m) with
the median distance between their pelvis floor points.

    python benchmarks/history/live_vtest.py ../shared/data/real-video/vtest.avi \\
        --camera ../shared/data/real-video/vtest_camera.json --offline OUT/world.json --out DIR [--site F]
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
from ray3d.io.world import read_world
from ray3d.jobs import CameraChoice, Job
from ray3d.jobs.live import live_job, local_inputs
from ray3d.live.runner import LiveOptions
from ray3d.live.source import FrameSource, SourceGroup
from ray3d.metrics import match_tracks
from ray3d.site.files import read_site
from ray3d.video import make_detector


def _feed_latencies(url: str, arrivals: dict, out: list, stop: threading.Event) -> None:
    """Read the page's feed as a browser does; for each snapshot, the time since its frame arrived."""
    with urllib.request.urlopen(url + "stream", timeout=30) as feed:
        for line in feed:
            if stop.is_set():
                return
            if line.startswith(b"data: {\"frame\""):
                received = time.monotonic()
                frame = json.loads(line[6:])["frame"]
                if frame in arrivals:
                    out.append(1000.0 * (received - arrivals[frame]))


def _summary(world) -> dict:
    refined = [r.refinement for r in world.tracks.values() if r.refinement]
    contact = [r["contact_fraction"] for r in refined]
    statures = [r["stature_m"] for r in refined]
    seen = [r["contact_fraction"] / r["floor_cue_fraction"] for r in refined if r["floor_cue_fraction"] > 0]
    return {"tracks": len(world.tracks), "feet_on_floor": float(np.mean(contact)),
            "feet_on_floor_where_seen": float(np.mean(seen)),
            "stature_median": float(np.median(statures)), "stature_range": [float(min(statures)), float(max(statures))]}


def _matched_distances(live, offline) -> tuple[list[float], int]:
    matches = match_tracks(live.tracks, offline.tracks, within_m=1.0)
    return [d for m in matches for d in m.distances_m.tolist()], len(matches)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("video")
    parser.add_argument("--camera", required=True)
    parser.add_argument("--offline", type=Path, required=True, help="the world file of ray3d video on it")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--site", type=Path)
    parser.add_argument("--detector", default="combined")
    args = parser.parse_args()
    camera = read_camera(args.camera)
    source = FrameSource.open(args.video)
    arrivals: dict[int, float] = {}
    original_next = source.next

    def next_frame():  # note when each frame arrived, for the feed's latency
        frame = original_next()
        if frame is not None:
            arrivals[frame.index] = frame.arrived
        return frame

    source.next = next_frame
    detector = make_detector(args.detector, camera, live=True)
    detector.prepare([])
    page_latency: list[float] = []
    stop_feed = threading.Event()

    def started(url: str) -> None:
        threading.Thread(target=_feed_latencies, args=(url, arrivals, page_latency, stop_feed), daemon=True).start()

    begun = time.monotonic()
    summary = live_job(Job((args.video,), (CameraChoice(args.camera),)), args.out, LiveOptions(port=0),
                       lambda job, recorder: local_inputs(job, SourceGroup([source]), [camera], [detector]),
                       site=read_site(args.site) if args.site else None, started=started).summary
    stop_feed.set()
    wall = time.monotonic() - begun
    live, offline = read_world(summary.files["world"]), read_world(args.offline)
    distances, matched = _matched_distances(live, offline)
    report = {
        "ending": summary.why, "wall_s": round(wall, 1), "read": summary.read, "processed": summary.processed,
        "dropped": summary.dropped, "dropped_percent": round(100 * summary.dropped / summary.read, 2),
        "latency_published_ms": {"median": float(np.median(summary.latency_ms)),
                                 "p99": float(np.percentile(summary.latency_ms, 99))},
        "latency_page_feed_ms": {"median": float(np.median(page_latency)),
                                 "p99": float(np.percentile(page_latency, 99)),
                                 "snapshots": len(page_latency)} if page_latency else None,
        "people_postponed": summary.postponed,
        "person_frames_written": int(sum(len(r.frames) for r in live.tracks.values())),
        "events": summary.events, "live": _summary(live), "offline": _summary(offline),
        "matched_tracks": matched, "pelvis_floor_distance_m": {"median": float(np.median(distances)),
                                                               "p90": float(np.percentile(distances, 90)),
                                                               "frames": len(distances)}}
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
