"""``follow``: cameras following their streams in; people, events, the page and the world files out, as the frames
arrive.

Each frame taken from a source (the newest; those that came while the last was processed are dropped and
counted) goes through detection, tracking and causal lifting (``LivePeople``), the site's events
(``ray3d.site.SiteMonitor``), the event log, the webhook and the page. A person who leaves is lifted again
offline, on a thread of its own, as ``ray3d video`` lifts them, and appended to the world file
(``append_world_csv``): the file holds every finished person and can be read at any moment. When the stream ends,
stalls or is stopped, everybody still in view is finished the same way and every output is closed (a live job,
``ray3d.jobs.live.live_job``, opens the streams and then fuses several cameras' world files and writes the site's
report)."""

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
from ray3d.geometry.uncertainty import PersonNow
from ray3d.live.health import BEHIND_SHARE, WINDOW_S, Keeping
from ray3d.live.outputs import Webhook
from ray3d.live.server import LiveBoard, LiveServer
from ray3d.live.source import FrameSource, SourceGroup, StreamStalled
from ray3d.live.views import Views
from ray3d.site.analytics import TimeBuckets
from ray3d.site.events import SiteMonitor
from ray3d.site.files import EventLines
from ray3d.site.places import Site
from ray3d.video.tracking import CLAIM_S

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
    behind_window_s: float = WINDOW_S  # falling behind: more than behind_share of this window's frames dropped
    behind_share: float = BEHIND_SHARE


@dataclasses.dataclass
class LiveSummary:
    """How it went: why it ended (one of ``ENDINGS``, with the line saying so), the frames read, processed and
    dropped, the people the detector left for the next frame to keep up, each processed frame's latency
    (arrival to its people published, milliseconds), the events, the tracks written and those left out (with
    why), the webhook's counts, the files written and, with several cameras, who each world person was
    ({person: [(camera index, track), ...]}, as ``joined.jsonl`` records it: the join the tail fuses by)."""

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
    behind: list = dataclasses.field(default_factory=list)  # the stretches it fell behind in (``health.Stretch``)
    joined: dict = dataclasses.field(default_factory=dict)


def _snapshot(frame_index: int, fps: float, people: list[PersonNow], trails: dict, monitor: SiteMonitor,
              latest: deque, stats: dict, buckets: TimeBuckets | None, floor: list[dict],
              health: dict | None = None) -> dict:
    occupancy = {zone: len(inside) for zone, inside in monitor.occupants.items()}  # as the events count it
    return {"frame": frame_index, "time_s": frame_index / fps,
            "people": [{"track": p.track, "x": round(float(p.joints[0, 0]), 3), "y": round(float(p.joints[0, 1]), 3),
                        "joints": np.round(p.joints, 3).tolist(), "position_sd_m": np.round(p.position_sd, 3).tolist(),
                        "stature_m": p.stature_m} for p in people],
            "trails": {t: [list(xy) for xy in trail] for t, trail in trails.items()},
            "counts": monitor.counts, "occupancy": occupancy, "events": list(latest), "stats": stats,
            "buckets": buckets.rows(frame_index / fps)[-RECENT_BUCKETS:] if buckets else [],
            "floor": floor, "health": health or {"falling_behind": False, "stretches": []}}


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
    are then completed by ``follow``. Returns the list the signals caught are added to (for the exit code)."""
    import signal

    caught: list[int] = []

    def on_signal(number, _frame) -> None:
        caught.append(number)
        stop.set()
        source.close()

    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, on_signal)
    return caught


class _Outputs:
    """Where a run's events go as they are found: the event log (and stdout), the store, the time buckets, the
    webhook, MQTT and the page's latest events; and the settled frames' people, to the store."""

    def __init__(self, events_path: Path, options: LiveOptions, monitor: SiteMonitor, recorder, mqtt,
                 buckets: TimeBuckets | None, label: str):
        self.log = EventLines(events_path, options.echo)
        self.webhook = Webhook(options.webhook, token=options.token) if options.webhook else None
        self.monitor, self.recorder, self.mqtt, self.buckets, self.label = monitor, recorder, mqtt, buckets, label
        self.latest: deque = deque(maxlen=LATEST_EVENTS)
        self.count = 0
        self.last_index = -1  # the last frame settled

    def settle(self, settled: tuple[int, list[PersonNow]]) -> list[dict]:
        """A settled frame's events (none when it is not newer than the last), its people to the store."""
        if settled[0] <= self.last_index:
            return []
        self.last_index = settled[0]
        if self.recorder is not None:
            self.recorder.positions(settled[0] / self.monitor.fps, settled[1], self.label)
        return _monitored(self.monitor, settled, self.buckets)

    def emit(self, events: list[dict]) -> None:
        self._sent(events)
        if self.recorder is not None:
            self.recorder.events(events)
        if self.buckets is not None:
            self.buckets.add(events)
        self.latest.extend(events)
        self.count += len(events)

    def taken_over(self, closed: list[dict]) -> None:
        """The events that closed what the run before left open (``store.RunRecorder.closed``, in the store
        already) to the event log, the webhook and MQTT; not to this run's counts."""
        self._sent(closed)

    def _sent(self, events: list[dict]) -> None:
        """``events`` to the event log, the webhook and MQTT."""
        self.log.write(events)
        if self.webhook:
            self.webhook.post(events)
        if self.mqtt is not None:
            self.mqtt.publish(events, self.monitor)

    def close(self) -> dict:
        """Every output closed (the store is closed by the run, with how it ended); the webhook's counts."""
        self.log.close()
        if self.mqtt is not None:
            self.mqtt.close()
        if not self.webhook:
            return {}
        self.webhook.close()
        return {"delivered": self.webhook.delivered, "failed": self.webhook.failed, "dropped": self.webhook.dropped}


class _Pace:
    """Each processed frame's latency (arrival to its people published, ms) and the recent rate, for the page."""

    def __init__(self):
        self.latencies: list[float] = []
        self.recent_latency, self.recent_times = deque(maxlen=100), deque(maxlen=30)

    def add(self, arrived: float, cameras) -> dict:
        now = time.monotonic()
        self.recent_times.append(now)
        latency = 1000.0 * (now - arrived)
        self.latencies.append(latency)
        self.recent_latency.append(latency)
        times = self.recent_times
        rate = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0
        return {"fps": rate, "latency_median_ms": float(np.median(self.recent_latency)),
                "latency_p99_ms": float(np.percentile(self.recent_latency, 99)), "dropped": cameras.dropped,
                "read": cameras.read}


def _ended_on_purpose(until_s: float | None, stop: threading.Event, cameras) -> tuple[threading.Timer | None,
                                                                                    threading.Event]:
    """A timer that ends the run after ``until_s`` seconds (None: none), and the flag it sets."""
    reached = threading.Event()
    if until_s is None:
        return None, reached

    def end() -> None:
        reached.set()
        stop.set()
        cameras.close()

    timer = threading.Timer(max(0.0, until_s), end)
    timer.daemon = True
    timer.start()
    return timer, reached


def _keeping(cameras, options: LiveOptions, recorder) -> Keeping:
    """Whether the run keeps up with each camera's stream; each stretch it falls behind in recorded in the store."""
    def recorded(stretch) -> None:
        if recorder is not None:
            recorder.behind(stretch.camera, stretch.from_s, stretch.to_s, stretch.share)

    return Keeping([str(name) for name in cameras.names], list(cameras.fps), options.behind_window_s,
                   options.behind_share, recorded=recorded)


def _read_and_dropped(cameras, view: int, result) -> tuple[int, int, int]:
    """A camera's frames read and dropped and people left for the next frame so far: from its actor (Ray), or from
    its source and detector in this process."""
    if hasattr(cameras, "workers"):  # RayCameras: over every incarnation of the camera's actor
        worker = cameras.workers[view]
        return tuple(before + now for before, now in zip(worker.before, worker.counts))
    if hasattr(cameras, "group"):
        source = cameras.group.sources[view]
        return source.read, source.dropped, cameras.views[view].postponed()
    return cameras.read, cameras.dropped, cameras.postponed


def _refused(cameras, error: InputError):
    cameras.close()
    cameras.finish()
    raise error


def follow(cameras, out_dir: str | Path, site: Site | None = None, options: LiveOptions = LiveOptions(),
           stop: threading.Event | None = None, started=lambda url: None,
           offsets_s: list[float] | None = None, recorder=None, mqtt=None, min_track_s: float = 0.0) -> LiveSummary:
    """The live loop over cameras already following their streams (``live.cameras.LocalCameras`` in
    this process, ``live.cluster.RayCameras`` on Ray): their people joined, the site's events, the event log,
    the webhook, MQTT (``mqtt``: a ``live.mqtt.MqttPublisher``), the page, each camera's world file and the
    site's store (``recorder``: a ``store.RunRecorder``; a run that continues a store's record appends to the
    event log and the world files its earlier runs wrote, first the events that closed what a killed run left open,
    and MQTT's running counts go on from the store's). A person is announced ("track started") once followed for
    ``min_track_s`` (the job's shortest track) or at their first other event (``SiteMonitor``'s
    ``announced_after_s``)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    events_path = out_dir / "events.jsonl"
    if events_path.exists() and not (recorder and recorder.continues):
        _refused(cameras, InputError(f"{events_path}: exists; ray3d live never writes over an output", ("out",)))
    stop = stop or threading.Event()
    site = site or Site()
    try:
        views = Views(cameras, out_dir, offsets_s, recorder)
    except InputError as err:
        _refused(cameras, err)
    # The people a run cut off left in view go on where its tracker takes them up; those it has not after its
    # first seconds (and a margin for the frames held before they settle) are ended where they were left.
    monitor = SiteMonitor(site, views.fps, recorder.carried if recorder is not None else (), min_track_s)
    giving_up_frames, first_settled = int(round((CLAIM_S + 2.0) * views.fps)), None
    buckets = TimeBuckets(site, options.every_s, options.start_time) if options.every_s else None
    board = LiveBoard({"zones": [{"name": z.name, "polygon": z.polygon.tolist()} for z in site.zones],
                       "lines": [{"name": line.name, "start": line.start.tolist(), "end": line.end.tolist()}
                                 for line in site.lines]})
    server = LiveServer(board, options.host, options.port, options.token) if options.page else None
    outputs = _Outputs(events_path, options, monitor, recorder, mqtt, buckets, views.label)
    if mqtt is not None:  # its counts going on from the store's
        mqtt.begin(monitor, recorder.counted if recorder is not None else None)
    if recorder is not None:
        outputs.taken_over(recorder.closed)
    trails: dict[str, deque] = {}
    pace, processed = _Pace(), 0
    keeping = _keeping(cameras, options, recorder)
    ending, why = "stopped", f"{cameras.name}: stopped"
    timer, reached = _ended_on_purpose(options.until_s, stop, cameras)
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
                keeping.observe(view, result.index / cameras.fps[view] - views.offsets_s[view],
                                *_read_and_dropped(cameras, view, result), stride=result.stride)
                if mqtt is not None:
                    mqtt.health(keeping.state())
                settled, persons, leaving = views.take(view, result)
                events = [event for frame in settled for event in outputs.settle(frame)]
                if settled and monitor.carrying:
                    first_settled = settled[0][0] if first_settled is None else first_settled
                    if settled[-1][0] > first_settled + giving_up_frames:
                        events += monitor.give_up()
                for person in leaving:
                    events += monitor.ended(person)
                    trails.pop(person, None)
                outputs.emit(events)
                if recorder is not None:  # a track that ended unannounced has no "track ended" to say so
                    recorder.left(list(leaving))
                views.recorded(view, result)
                for person in persons:
                    trail = trails.setdefault(person.track, deque(maxlen=max(2, int(options.trail_s * views.fps))))
                    trail.append((round(float(person.joints[0, 0]), 2), round(float(person.joints[0, 1]), 2)))
                processed += 1
                board.publish(_snapshot(outputs.last_index, views.fps, persons, trails, monitor, outputs.latest,
                                        pace.add(result.arrived, cameras), buckets, views.floor_lines(),
                                        keeping.state()))
    finally:
        if timer is not None:
            timer.cancel()
        if reached.is_set():
            ending, why = "until", f"{cameras.name}: ended after {options.until_s:g} s, as asked"
        cameras.close()
        settled, leaving = views.finish()
        for frame in settled:
            outputs.emit(outputs.settle(frame))
        outputs.emit(monitor.give_up())
        for person, _ in leaving:
            outputs.emit(monitor.ended(person))
        if recorder is not None:
            recorder.left([person for person, _ in leaving])
        keeping.finish()
        if mqtt is not None:
            mqtt.health(keeping.state())
        webhook = outputs.close()
        if recorder is not None:
            recorder.close(ending)
        if server:
            server.stop()
    files = {"events": events_path, "world": views.world_paths[0], "worlds": views.world_paths}
    return LiveSummary(ending, why, cameras.read, processed, cameras.dropped, cameras.postponed,
                       np.array(pace.latencies), outputs.count, views.written, views.left_out, webhook, files,
                       keeping.stretches, views.joined)
