"""``run_live``: a stream of frames in; people, events, the page and the world file out, as the frames arrive.

Each frame taken from the source (the newest; those that came while the last was processed are dropped and
counted) goes through detection, tracking and causal lifting (``LivePeople``), the site's events
(``ray3d.site.SiteMonitor``), the event log, the webhook and the page. A person who leaves is lifted again
offline, on a thread of its own, as ``ray3d video`` lifts them, and appended to the world file
(``append_world_csv``): the file holds every finished person and can be read at any moment. When the stream ends, stalls or is stopped, everybody still in view is
finished the same way and every output is closed (a live job then fuses several cameras' world files and writes
the site's report: ``ray3d.jobs.live``)."""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import threading
import time
from collections import deque
from pathlib import Path
from typing import TextIO

import numpy as np

from ray3d.errors import InputError
from ray3d.io.world import append_world_csv
from ray3d.lifting.lifter import Lifter
from ray3d.site.files import EventLines
from ray3d.live.outputs import Webhook
from ray3d.live.cameras import FrameResult, LocalCameras
from ray3d.geometry.uncertainty import PersonNow
from ray3d.live.server import LiveBoard, LiveServer
from ray3d.fusion.live import LiveFusion
from ray3d.live.source import FrameSource, SourceGroup, StreamStalled
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.site.analytics import TimeBuckets, stature_class
from ray3d.site.events import SiteMonitor
from ray3d.site.places import Site

ENDINGS = ("ended", "stalled", "broke off", "stopped", "until")
LATEST_EVENTS = 20  # events the page shows
RECENT_BUCKETS = 12  # time buckets the page shows


@dataclasses.dataclass(frozen=True)
class LiveOptions:
    """How the stream is served and followed: the page (``page``, ``host``, ``port``, ``token``), the
    ``webhook`` URL, ``echo`` events on a text stream (stdout), ``trail_s`` of each path on the page, counts per
    ``every_s`` seconds (wall-clock from ``start_time``) on the page and in the site's report. (Who is
    followed how, a person's longest gap and the shortest track written, is the job's ``VideoOptions``.)"""

    page: bool = True
    host: str = "127.0.0.1"
    port: int = 8765
    token: str | None = None
    webhook: str | None = None
    echo: TextIO | None = None
    trail_s: float = 10.0
    every_s: float | None = None  # the counts per time bucket of this length, on the page and in the report
    start_time: datetime.datetime | None = None  # the stream's first frame, for wall-clock buckets
    until_s: float | None = None  # end the run on purpose after this many seconds ("until")


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


def _snapshot(frame_index: int, fps: float, people: list[PersonNow], trails: dict, monitor: SiteMonitor,
              latest: deque, stats: dict, buckets: TimeBuckets | None) -> dict:
    occupancy = {zone.name: int(sum(bool(zone.contains(p.joints[0, :2])) for p in people))
                 for zone in monitor.site.zones}
    return {"frame": frame_index, "time_s": frame_index / fps,
            "people": [{"track": p.track, "x": round(float(p.joints[0, 0]), 3), "y": round(float(p.joints[0, 1]), 3),
                        "joints": np.round(p.joints, 3).tolist(), "position_sd_m": np.round(p.position_sd, 3).tolist(),
                        "stature_m": p.stature_m} for p in people],
            "trails": {t: [list(xy) for xy in trail] for t, trail in trails.items()},
            "counts": monitor.counts, "occupancy": occupancy, "events": list(latest), "stats": stats,
            "buckets": buckets.rows(frame_index / fps)[-RECENT_BUCKETS:] if buckets else []}


def _monitored(monitor: SiteMonitor, settled: tuple[int, list[PersonNow]], buckets: TimeBuckets | None) -> list[dict]:
    """The site's events of a settled frame (its index and its people), its occupancy counted in its bucket."""
    index, people = settled
    events = monitor.update(index, {person.track: person.joints for person in people})
    if buckets is not None:
        buckets.observe(index / monitor.fps, {zone: len(inside) for zone, inside in monitor.occupants.items()})
    return events


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


def stop_on_signals(stop: threading.Event, source: FrameSource | SourceGroup) -> list[int]:
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


class _Views:
    """What the cameras give, brought together: each camera's finished people appended to its world file; with
    several, their people joined into world people (``LiveFusion``) on the first camera's clock."""

    def __init__(self, cameras, out_dir: Path, offsets_s: list[float] | None, recorder=None):
        self.cameras, self.several, self.recorder = cameras, len(cameras.cameras) > 1, recorder
        self.fps = cameras.fps[0]
        count = len(cameras.cameras)
        self.offsets_s = list(offsets_s) if offsets_s is not None else [0.0] * count
        if len(self.offsets_s) != count:
            raise InputError(f"offsets: {len(self.offsets_s)} given for {count} cameras", ("offsets",))
        self.world_paths = [out_dir / "world.csv"] if not self.several else \
            [out_dir / f"camera{k + 1}_{_file_name(name)}" / "world.csv" for k, name in enumerate(cameras.names)]
        for path in self.world_paths:
            if path.exists() and not (recorder and recorder.continues):
                raise InputError(f"{path}: exists; ray3d live never writes over an output", ("out",))
            path.parent.mkdir(parents=True, exist_ok=True)
        self.fusion = LiveFusion(cameras.cameras, 1.0 / min(cameras.fps),
                                 id_prefix=recorder.id_prefix if recorder else "") if self.several else None
        self.written, self.left_out = 0, {}
        self.label = " + ".join(str(name) for name in cameras.names)  # who saw the world's people
        self._pending: tuple | None = None  # several cameras: the frame whose views are still coming in

    def take(self, view: int, result: FrameResult) -> tuple[tuple | None, list[PersonNow], list[str]]:
        """This camera's processed frame -> a frame settled for the site's events (its number on the first
        camera's clock and its people; None while it is not), the people now and those who left. With several
        cameras a frame is settled when the next begins: by then every camera's view of it is in."""
        self._write(view, result.done)
        if self.recorder is not None:
            self.recorder.progress(self.cameras.sources[view], result.index, self.time_s(view, result.index))
            if result.gap is not None:
                self.recorder.gap(self.cameras.names[view], *result.gap, "the stream was down")
        if not self.several:
            return (result.index, result.persons), result.persons, result.ended
        time_s = result.index / self.cameras.fps[view] - self.offsets_s[view]
        for track in result.ended:
            self.fusion.finished(view, track)
        persons = self.fusion.update(view, time_s, result.persons)
        index, settled = int(round(time_s * self.fps)), None
        if self._pending is None or index > self._pending[0]:
            settled, self._pending = self._pending, (index, persons)
        else:
            self._pending = (self._pending[0], persons)
        return settled, persons, self.fusion.ended(time_s)

    def finish(self) -> tuple[tuple | None, list[tuple[str, int]]]:
        """Everybody still in view handed over: the last frame not settled yet (None if none) and who leaves
        (person, the first camera's frame they were last seen in)."""
        leaving = []
        for view, (in_view, done) in enumerate(self.cameras.finish()):
            self._write(view, done)
            for track, last_frame in in_view:
                if self.several:
                    self.fusion.finished(view, track)
                else:
                    leaving.append((track, last_frame))
        if self.several:
            leaving = [(n, int(round(seen_s * self.fps))) for n, seen_s in self.fusion.ended(np.inf, seen=True)]
        return self._pending, leaving

    def time_s(self, view: int, index: int) -> float:
        """A frame of camera ``view`` on the first camera's clock (seconds)."""
        return index / self.cameras.fps[view] - self.offsets_s[view]

    def _write(self, view: int, done: list) -> None:
        for finished in done:
            if finished.world is None:
                self.left_out[f"{view + 1}:{finished.track}" if self.several else finished.track] = finished.why
                continue
            append_world_csv(self.world_paths[view], finished.world)
            self.written += 1
            if self.recorder is not None:
                track = next(iter(finished.world.tracks.values()))
                refinement = track.refinement or {}
                stature = refinement.get("stature_m")
                self.recorder.person(finished.track, self.time_s(view, int(track.frames[0])),
                                     self.time_s(view, int(track.frames[-1])), stature,
                                     stature_class(stature, refinement.get("stature_interval_m")),
                                     len(finished.world.rejoined.get(finished.track, ()) if finished.world.rejoined
                                         else ()), self.cameras.names[view])


def _file_name(name: str) -> str:
    """A camera's or a stream's name as a folder name."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in Path(str(name)).stem) or "camera"


def _several(value) -> list:
    return list(value) if isinstance(value, (list, tuple)) else [value]


def run_live(source, camera, out_dir: str | Path, detector, lifter: Lifter | None = None,
             site: Site | None = None, options: LiveOptions = LiveOptions(),
             lift_options: LiftOptions = LiftOptions(), stop: threading.Event | None = None,
             started=lambda url: None, offsets_s: list[float] | None = None,
             video_options: VideoOptions = VideoOptions(), recorder=None) -> LiveSummary:
    """Follow ``source`` until it ends, stalls, breaks off or ``stop`` is set; write ``out_dir``/events.jsonl
    and world.csv. ``started(url)`` is called once the page listens.

    Several cameras: ``source``, ``camera`` and ``detector`` are lists, one each per camera (``offsets_s``: how
    far each camera's clock is ahead of the first's, 0 by default); each camera's people are written to
    ``out_dir``/camera<k>_<name>/world.csv, the events and the page are of the world's people (``LiveFusion``);
    ``ray3d.jobs.live.run_live_job`` fuses those files at the end. ``recorder``: the site's store
    (``store.RunRecorder``; its run's number prefixes every track id)."""
    sources = source.sources if isinstance(source, SourceGroup) else _several(source)
    cameras, detectors = _several(camera), _several(detector)
    if not len(sources) == len(cameras) == len(detectors):
        raise InputError(f"cameras: {len(cameras)} cameras and {len(detectors)} detectors for {len(sources)} "
                         "streams; give one each per stream", ("camera",))
    lifter = lifter or Lifter.load(layout=detectors[0].layout)
    lifter.prepare_small_batches()  # before the first frame is taken (it pauses 0.2 s; the source may be running)
    group = source if isinstance(source, SourceGroup) else SourceGroup(sources)
    followed = LocalCameras(group, cameras, detectors, lifter, lift_options, video_options.max_gap_s,
                            video_options.min_track_s, recorder.id_prefix if recorder else "")
    return follow(followed, out_dir, site, options, stop, started, offsets_s, recorder)


def follow(cameras, out_dir: str | Path, site: Site | None = None, options: LiveOptions = LiveOptions(),
           stop: threading.Event | None = None, started=lambda url: None,
           offsets_s: list[float] | None = None, recorder=None, mqtt=None) -> LiveSummary:
    """The loop of ``run_live`` over cameras already following their streams (``live.cameras.LocalCameras`` in
    this process, ``live.cluster.RayCameras`` on Ray): their people joined, the site's events, the event log,
    the webhook, MQTT (``mqtt``: a ``live.mqtt.MqttPublisher``), the page, each camera's world file and the
    site's store (``recorder``: a ``store.RunRecorder``; a run that continues a store's record appends to the
    event log and the world files its earlier runs wrote)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    events_path = out_dir / "events.jsonl"
    if events_path.exists() and not (recorder and recorder.continues):
        cameras.close()
        cameras.finish()
        raise InputError(f"{events_path}: exists; ray3d live never writes over an output", ("out",))
    stop = stop or threading.Event()
    site = site or Site()
    try:
        views = _Views(cameras, out_dir, offsets_s, recorder)
    except InputError:
        cameras.close()
        cameras.finish()
        raise
    monitor = SiteMonitor(site, views.fps)
    buckets = TimeBuckets(site, options.every_s, options.start_time) if options.every_s else None
    board = LiveBoard({"zones": [{"name": z.name, "polygon": z.polygon.tolist()} for z in site.zones],
                       "lines": [{"name": l.name, "start": l.start.tolist(), "end": l.end.tolist()}
                                 for l in site.lines]})
    server = LiveServer(board, options.host, options.port, options.token) if options.page else None
    log = EventLines(events_path, options.echo)
    webhook = Webhook(options.webhook, token=options.token) if options.webhook else None
    trails: dict[str, deque] = {}
    latest: deque = deque(maxlen=LATEST_EVENTS)
    latencies, recent_latency, recent_times = [], deque(maxlen=100), deque(maxlen=30)
    processed = events_count = 0
    last_index = -1
    ending, why = "stopped", f"{cameras.name}: stopped"

    def emit(events: list[dict]) -> None:
        nonlocal events_count
        log.write(events)
        if recorder is not None:
            recorder.events(events)
        if buckets is not None:
            buckets.add(events)
        if webhook:
            webhook.post(events)
        if mqtt is not None:
            mqtt.publish(events, monitor)
        latest.extend(events)
        events_count += len(events)

    reached = threading.Event()
    timer = None
    if options.until_s is not None:
        def end_on_purpose() -> None:
            reached.set()
            stop.set()
            cameras.close()

        timer = threading.Timer(max(0.0, options.until_s), end_on_purpose)
        timer.daemon = True
        timer.start()
    try:
        if server:
            started(server.start())
        with _one_thread_for_numerics():
            while not stop.is_set():
                try:
                    taken = cameras.next()
                except StreamStalled as err:
                    ending, why = "stalled", err.message
                    break
                except InputError as err:
                    ending, why = "broke off", err.message
                    break
                if taken is None:
                    if not stop.is_set():
                        ending, why = "ended", f"{cameras.name}: the stream ended"
                    break
                view, result = taken
                settled, persons, leaving = views.take(view, result)
                if recorder is not None and settled is not None and settled[0] > last_index:
                    recorder.positions(settled[0] / views.fps, settled[1], views.label)
                events = _monitored(monitor, settled, buckets) if settled is not None and settled[0] > last_index else []
                last_index = max(last_index, settled[0] if settled is not None else last_index)
                for person in leaving:
                    events += monitor.ended(person)
                    trails.pop(person, None)
                emit(events)
                for person in persons:
                    trail = trails.setdefault(person.track, deque(maxlen=max(2, int(options.trail_s * views.fps))))
                    trail.append((round(float(person.joints[0, 0]), 2), round(float(person.joints[0, 1]), 2)))
                processed += 1
                now = time.monotonic()
                recent_times.append(now)
                latency = 1000.0 * (now - result.arrived)
                latencies.append(latency)
                recent_latency.append(latency)
                rate = (len(recent_times) - 1) / (recent_times[-1] - recent_times[0]) if len(recent_times) > 1 else 0.0
                board.publish(_snapshot(last_index, views.fps, persons, trails, monitor, latest, {
                    "fps": rate, "latency_median_ms": float(np.median(recent_latency)),
                    "latency_p99_ms": float(np.percentile(recent_latency, 99)), "dropped": cameras.dropped,
                    "read": cameras.read}, buckets))
    finally:
        if timer is not None:
            timer.cancel()
        if reached.is_set():
            ending, why = "until", f"{cameras.name}: ended after {options.until_s:g} s, as asked"
        cameras.close()
        settled, leaving = views.finish()
        if settled is not None and settled[0] > last_index:
            if recorder is not None:
                recorder.positions(settled[0] / views.fps, settled[1], views.label)
            emit(_monitored(monitor, settled, buckets))
        for person, _ in leaving:
            emit(monitor.ended(person))
        log.close()
        if webhook:
            webhook.close()
        if mqtt is not None:
            mqtt.close()
        if recorder is not None:
            recorder.close(ending)
        if server:
            server.stop()
    files = {"events": events_path, "world": views.world_paths[0], "worlds": views.world_paths}
    return LiveSummary(ending, why, cameras.read, processed, cameras.dropped, cameras.postponed,
                       np.array(latencies), events_count,
                       views.written, views.left_out,
                       {} if not webhook else {"delivered": webhook.delivered, "failed": webhook.failed,
                                               "dropped": webhook.dropped}, files)
