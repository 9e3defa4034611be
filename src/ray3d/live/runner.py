"""``run_live``: a stream of frames in; people, events, the page and the world file out, as the frames arrive.

Each frame taken from the source (the newest; those that came while the last was processed are dropped and
counted) goes through detection, tracking and causal lifting (``LivePeople``), the site's events (``LiveSite``),
the event log, the webhook and the page. A person who leaves is lifted again offline, on a thread of its own, as
``ray3d video`` lifts them, and appended to the world file (``append_world_csv``): the file holds every finished
person and can be read at any moment. When the stream ends, stalls or is stopped, everybody still in view is
finished the same way, every output is closed, and with a site the report of ``ray3d site`` is written."""

from __future__ import annotations

import contextlib
import dataclasses
import queue
import threading
import time
from collections import deque
from pathlib import Path
from typing import TextIO

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.world import World, append_world_csv, read_world
from ray3d.lift import Lifter
from ray3d.live.events import LiveSite
from ray3d.live.outputs import EventLog, Webhook
from ray3d.live.people import LivePeople, PersonNow, below_the_stream
from ray3d.live.server import LiveBoard, LiveServer
from ray3d.live.source import FrameSource, StreamStalled
from ray3d.options import LiftOptions
from ray3d.site import Site
from ray3d.video.tracking import Track

ENDINGS = ("ended", "stalled", "broke off", "stopped")
LATEST_EVENTS = 20  # events the page shows


@dataclasses.dataclass(frozen=True)
class LiveOptions:
    """How the stream is served and followed: the page (``page``, ``host``, ``port``, ``token``), the
    ``webhook`` URL, ``echo`` events on a text stream (stdout), a track shorter than ``min_track_s`` is left out
    of the world file, a person unseen for ``max_gap_s`` has left, ``trail_s`` of each path on the page."""

    page: bool = True
    host: str = "127.0.0.1"
    port: int = 8765
    token: str | None = None
    webhook: str | None = None
    echo: TextIO | None = None
    min_track_s: float = 1.0
    max_gap_s: float = 0.5
    trail_s: float = 10.0


@dataclasses.dataclass
class LiveSummary:
    """How it went: why it ended (one of ``ENDINGS``, with the line saying so), the frames read, processed and
    dropped, the people the detector left for the next frame to keep up, each processed frame's latency
    (arrival to its people published, milliseconds), the events, the tracks written and those left out (with
    why), the webhook's counts and the files written."""

    ending: str
    why: str
    read: int
    processed: int
    dropped: int
    postponed: int
    latency_ms: np.ndarray
    events: int
    tracks: int
    left_out: dict
    webhook: dict
    files: dict


class _Finisher:
    """Finished tracks lifted offline and appended to the world file, on a thread of its own (a bounded queue:
    the stream waits rather than lose a track)."""

    def __init__(self, lifter: Lifter, camera: Camera, layout: str, fps: float, path: Path,
                 lift_options: LiftOptions, min_track_s: float):
        self.lifter, self.camera, self.layout, self.fps, self.path = lifter, camera, layout, fps, path
        self.lift_options, self.min_track_s = lift_options, min_track_s
        self.written, self.left_out = 0, {}
        self._queue: queue.Queue = queue.Queue(maxsize=64)
        self._thread = threading.Thread(target=self._run, name="finisher", daemon=True)
        self._thread.start()

    def put(self, track: Track) -> None:
        self._queue.put(track)

    def _run(self) -> None:
        below_the_stream()
        while (track := self._queue.get()) is not None:
            self._finish(track)

    def _finish(self, track: Track) -> None:
        seconds = track.seconds(self.fps)
        if seconds < self.min_track_s:
            self.left_out[str(track.id)] = f"seen for {seconds:.2f} s (under {self.min_track_s:.2f} s)"
            return
        try:
            lifted = self.lifter.lift_tracks({str(track.id): track.as_detections()}, self.camera, self.layout,
                                             self.fps, **self.lift_options.lift_arguments())
        except InputError as err:
            self.left_out[str(track.id)] = err.message
            return
        except Exception as err:  # one person's failure must not stop the others being written
            self.left_out[str(track.id)] = f"could not be lifted ({type(err).__name__}: {err})"
            return
        append_world_csv(self.path, World(lifted, self.camera, self.lifter.name).in_frame("world"))
        self.written += 1

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()


def _snapshot(frame_index: int, fps: float, people: list[PersonNow], trails: dict, monitor: LiveSite,
              latest: deque, stats: dict) -> dict:
    occupancy = {zone.name: int(sum(bool(zone.contains(p.joints[0, :2])) for p in people))
                 for zone in monitor.site.zones}
    return {"frame": frame_index, "time_s": frame_index / fps,
            "people": [{"track": p.track, "x": round(float(p.joints[0, 0]), 3), "y": round(float(p.joints[0, 1]), 3),
                        "joints": np.round(p.joints, 3).tolist(), "position_sd_m": np.round(p.position_sd, 3).tolist(),
                        "stature_m": p.stature_m} for p in people],
            "trails": {str(t): [list(xy) for xy in trail] for t, trail in trails.items()},
            "counts": monitor.counts, "occupancy": occupancy, "events": list(latest), "stats": stats}


@contextlib.contextmanager
def _one_thread_for_numerics():
    """NumPy's BLAS and torch held to one thread each while the stream runs: their idle threads spin, taking
    the cores the detector's network runs on, and the lifting's matrices are small. Given back at the end."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # without the live extra: BLAS as it is
        def threadpool_limits(**_):
            return contextlib.nullcontext()
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        torch.set_num_threads(threads)


def stop_on_signals(stop: threading.Event, source: FrameSource) -> list[int]:
    """SIGINT (Ctrl-C) and SIGTERM end the stream cleanly: ``stop`` is set and ``source`` closed, the outputs
    are then completed by ``run_live``. Returns the list the signals caught are added to (for the exit code)."""
    import signal

    caught: list[int] = []

    def on_signal(number, _frame) -> None:
        caught.append(number)
        stop.set()
        source.close()

    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, on_signal)
    return caught


def run_live(source: FrameSource, camera: Camera, out_dir: str | Path, detector, lifter: Lifter | None = None,
             site: Site | None = None, options: LiveOptions = LiveOptions(),
             lift_options: LiftOptions = LiftOptions(), stop: threading.Event | None = None,
             started=lambda url: None) -> LiveSummary:
    """Follow ``source`` until it ends, stalls, breaks off or ``stop`` is set; write ``out_dir``/events.jsonl
    and world.csv (and site/ with a site). ``started(url)`` is called once the page listens."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {"events": out_dir / "events.jsonl", "world": out_dir / "world.csv"}
    for path in files.values():
        if path.exists():
            raise InputError(f"{path}: exists; ray3d live never writes over an output", ("out",))
    stop = stop or threading.Event()
    lifter = lifter or Lifter.load(layout=detector.layout)
    site = site or Site()
    people = LivePeople(camera, detector, lifter, source.fps, lift_options.floor, options.max_gap_s,
                        deadline_frames=source.keep)
    monitor = LiveSite(site, source.fps)
    board = LiveBoard({"zones": [{"name": z.name, "polygon": z.polygon.tolist()} for z in site.zones],
                       "lines": [{"name": l.name, "start": l.start.tolist(), "end": l.end.tolist()}
                                 for l in site.lines]})
    server = LiveServer(board, options.host, options.port, options.token) if options.page else None
    log = EventLog(files["events"], options.echo)
    webhook = Webhook(options.webhook, token=options.token) if options.webhook else None
    finisher = _Finisher(lifter, camera, detector.layout, source.fps, files["world"], lift_options,
                         options.min_track_s)
    trails: dict[int, deque] = {}
    latest: deque = deque(maxlen=LATEST_EVENTS)
    latencies, recent_latency, recent_times = [], deque(maxlen=100), deque(maxlen=30)
    processed = events_count = 0
    ending, why = "stopped", f"{source.name}: stopped"

    def emit(events: list[dict]) -> None:
        nonlocal events_count
        log.write(events)
        if webhook:
            webhook.post(events)
        latest.extend(events)
        events_count += len(events)

    try:
        if server:
            started(server.start())
        with _one_thread_for_numerics():
            while not stop.is_set():
                try:
                    frame = source.next()
                except StreamStalled as err:
                    ending, why = "stalled", err.message
                    break
                except InputError as err:
                    ending, why = "broke off", err.message
                    break
                if frame is None:
                    if not stop.is_set():
                        ending, why = "ended", f"{source.name}: the stream ended"
                    break
                persons, finished = people.update(frame)
                events = monitor.update(frame.index, persons)
                for track in finished:
                    events += monitor.ended(track.id, frame.index)
                    trails.pop(track.id, None)
                    finisher.put(track)
                emit(events)
                for person in persons:
                    trail = trails.setdefault(person.track, deque(maxlen=max(2, int(options.trail_s * source.fps))))
                    trail.append((round(float(person.joints[0, 0]), 2), round(float(person.joints[0, 1]), 2)))
                processed += 1
                now = time.monotonic()
                recent_times.append(now)
                latency = 1000.0 * (now - frame.arrived)
                latencies.append(latency)
                recent_latency.append(latency)
                rate = (len(recent_times) - 1) / (recent_times[-1] - recent_times[0]) if len(recent_times) > 1 else 0.0
                board.publish(_snapshot(frame.index, source.fps, persons, trails, monitor, latest, {
                    "fps": rate, "latency_median_ms": float(np.median(recent_latency)),
                    "latency_p99_ms": float(np.percentile(recent_latency, 99)), "dropped": source.dropped,
                    "read": source.read}))
    finally:
        source.close()
        people.close()
        for track in people.in_view():
            emit(monitor.ended(track.id, track.frames[-1]))
            finisher.put(track)
        finisher.close()
        log.close()
        if webhook:
            webhook.close()
        if server:
            server.stop()
    if site.zones or site.lines:
        if files["world"].exists():
            from ray3d.viz.site_report import analyse_site

            analyse_site(read_world(files["world"]), site, out_dir / "site", title=f"ray3d live: {source.name}")
            files["site"] = out_dir / "site"
    return LiveSummary(ending, why, source.read, processed, source.dropped, getattr(detector, "postponed", 0),
                       np.array(latencies), events_count,
                       finisher.written, finisher.left_out,
                       {} if not webhook else {"delivered": webhook.delivered, "failed": webhook.failed,
                                               "dropped": webhook.dropped}, files)
