"""A live job (``live_job``), as ``ray3d live`` runs it: the store's record begun (``start_record``), MQTT
connected, its streams opened, each with its camera, detector and lifter (``open_live``: in this process, or with
``address`` each camera in a Ray actor, ``live.cluster``), followed as they arrive (``live.runner.follow``), and at
the end the same tail as an offline job, on this run's people: each camera's world file read once, several fused by
the join the live events used (kept in memory; ``joined.jsonl`` is its record) into one (``jobs.run.fuse_and_write``)
and, with a site, that world's report (``jobs.run.site_report``). However the run ends, what it opened is
closed."""

from __future__ import annotations

import dataclasses
import functools
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path

from ray3d.errors import InputError
from ray3d.io.atomic import write_text
from ray3d.io.world import World, read_world, write_world
from ray3d.jobs.cluster import start_ray
from ray3d.jobs.job import Job
from ray3d.jobs.run import camera_and_detector, fuse_and_write, site_report
from ray3d.live.cameras import LocalCameras
from ray3d.live.cluster import RayCameras
from ray3d.live.mqtt import MqttPublisher
from ray3d.live.reconnect import ReconnectingSource
from ray3d.live.runner import LiveOptions, LiveSummary, follow, stop_on_signals
from ray3d.live.source import FrameSource, SourceGroup
from ray3d.site.events import TRACK_ENDED
from ray3d.site.places import Site
from ray3d.store import RunRecorder
from ray3d.video.frames import VideoInfo


@dataclasses.dataclass
class LiveInputs:
    """A live job's cameras following their streams (``live.cameras.LocalCameras`` or ``live.cluster.RayCameras``:
    ``followed``), the Ray this job started, to stop at its end (None: none started), and the Ray ``address`` the
    cameras run on (None: this process)."""

    followed: object
    ray: object = None
    address: str | None = None

    @property
    def on_ray(self) -> bool:
        return isinstance(self.followed, RayCameras)


def local_inputs(job: Job, group, cameras: list, detectors: list, id_prefix: str = "", carried=()) -> LiveInputs:
    """Streams already open (a ``SourceGroup``), with a camera and a detector each, followed in this process by the
    job's lifter (``id_prefix`` before every track id: a store's run number; ``carried``: the people in view when
    the store's run before was cut off, ``RunRecorder.carried``)."""
    options = [job.lift_options(k) for k in range(len(cameras))]  # each camera on its own floor, as on Ray
    return LiveInputs(LocalCameras(group, cameras, detectors, job.lifter(detectors[0].layout), options,
                                   job.video, id_prefix, carried))


def start_record(job: Job, store, command: str, site=None, start_time=None) -> RunRecorder:
    """The store's record of this run begun (``store.RunRecorder``: ``store`` a file, SQLite, or a
    ``postgresql://`` URL): the run numbered, the gaps since the last one, where each file input is taken up.
    ``start_time`` (a ``datetime``): the wall-clock time of the inputs' frame 0 (default: now, or the clock of the
    run that began a file taken up)."""
    document = None
    if site is not None:
        document = {"zones": [{"name": z.name, "polygon": z.polygon.tolist()} for z in site.zones],
                    "lines": [{"name": line.name, "start": line.start.tolist(), "end": line.end.tolist()}
                              for line in site.lines]}
    sources = [str(source) for source in job.inputs]
    return RunRecorder(store, command, sources, [Path(s).is_file() for s in sources], document,
                       start_time.timestamp() if start_time is not None else None)


def open_stream(job: Job, k: int, paced: bool | None = None, stall_timeout_s: float = 10.0, first_index: int = 0,
                reconnect_max_s: float | None = None):
    """Input ``k`` of ``job`` opened as a stream (from frame ``first_index`` on, where it is a file), with its camera
    for the stream's image size and a detector that keeps up (``jobs.run.camera_and_detector``): (``FrameSource``,
    ``Camera``, detector), in this process or in a Ray actor. With ``reconnect_max_s``, a stream that is not a
    file is opened again whenever it stalls or breaks off (``live.source.ReconnectingSource``: tries from 1 s
    apart, doubling up to that many seconds)."""
    if reconnect_max_s is not None and not Path(str(job.inputs[k])).is_file():
        source = ReconnectingSource(job.inputs[k], job.video.fps, stall_timeout_s,
                                    backoff_s=min(1.0, reconnect_max_s), max_backoff_s=reconnect_max_s,
                                    report=lambda line: print(line, file=sys.stderr, flush=True))
    else:
        source = FrameSource.open(job.inputs[k], job.video.fps, paced, stall_timeout_s, first_index=first_index)
    camera, detector = camera_and_detector(job, k, VideoInfo(source.name, 0, source.fps, source.image_size), live=True)
    detector.prepare([])
    return source, camera, detector


def open_live(job: Job, paced: bool | None = None, stall_timeout_s: float = 10.0, address: str | None = None,
              workers: int | None = None, cpus_per_camera: float = 1.0, recorder=None,
              reconnect_max_s: float | None = None) -> LiveInputs:
    """Open every input of ``job`` as a stream (``open_stream``: a file, a device number, a URL; ``paced``: played
    at its own rate, the default for files; ``reconnect_max_s``: streams opened again when they stall or break
    off). With ``address`` (``"local"``: a local Ray with ``workers`` CPUs
    started for the job; ``"auto"``, ``"ray://HOST:PORT"``: a running cluster) each stream is opened, and its
    people found, in a Ray actor reserving ``cpus_per_camera``. With a ``recorder`` (``store.RunRecorder``), a
    file is taken up where the store's record of it ends, and track ids carry the run's number."""
    firsts = [r.first_index for r in recorder.resumes] if recorder else [0] * len(job.inputs)
    prefix = recorder.id_prefix if recorder else ""
    carried = recorder.carried if recorder else ()
    if address:
        ray, started = start_ray(address, workers, "live jobs on a cluster")
        arguments = [dict(opened=functools.partial(open_stream, job, k, paced, stall_timeout_s,
                                                   reconnect_max_s=reconnect_max_s),
                          lifter=job.lifter, lift_options=job.lift_options(k), first_index=firsts[k],
                          id_prefix=prefix, following=job.video, carried=carried)
                     for k in range(len(job.inputs))]
        played = [paced is not False] * len(job.inputs)  # an unpaced file waits for its reader; the rest play on
        try:
            return LiveInputs(RayCameras(ray, arguments, [str(s) for s in job.inputs], played, cpus_per_camera),
                              ray if started else None, address)
        except BaseException:
            if started:
                ray.shutdown()
            raise
    opened = [open_stream(job, k, paced, stall_timeout_s, firsts[k], reconnect_max_s) for k in range(len(job.inputs))]
    detectors = [detector for _, _, detector in opened]
    return local_inputs(job, SourceGroup([source for source, _, _ in opened]), [camera for _, camera, _ in opened],
                        detectors, prefix, carried)


@dataclasses.dataclass
class LiveRun:
    """How a live job went: its ``summary`` (``live.runner.LiveSummary``: why it ended, the frames, the latency,
    the events, every file written), the store's ``recorder`` (``store.RunRecorder``: the run's number and the rows
    written; None without a store), the ``mqtt`` publisher (its counts; None without) and the ``signal`` that
    stopped it (None: none)."""

    summary: LiveSummary
    recorder: RunRecorder | None = None
    mqtt: MqttPublisher | None = None
    signal: int | None = None


def live_job(job: Job, out_dir: str | Path, options: LiveOptions = LiveOptions(),
             streams: Callable[..., LiveInputs] = open_live, site: Site | None = None, store=None,
             mqtt: str | None = None, offsets_s: list[float] | None = None, command: str = "ray3d live",
             stop: threading.Event | None = None, started: Callable[[str], None] = lambda url: None,
             said: Callable[[str], None] = lambda line: None, signals: bool = False) -> LiveRun:
    """``job``'s streams followed into ``out_dir`` until they end, stall, break off, ``options.until_s`` comes or
    ``stop`` is set (with ``signals``, SIGINT and SIGTERM set it, ``live.runner.stop_on_signals``, until the run's
    outputs are complete, when the caller's handlers are put back); then the tail:
    several cameras' world files fused into ``out_dir``/world.json, the site's report in ``out_dir``/site (a run
    continuing a store's record: in ``out_dir``/run<N>/, nothing written before is replaced).

    ``streams(job, recorder=...)`` opens them (``open_live``; bind its options with
    ``functools.partial``). ``site``: a ``site.places.Site`` (default the job's site file's). ``store``: the site's
    store the run is recorded in (a file, SQLite, or a ``postgresql://`` URL, ``start_record``: a file input is
    taken up where its record ends, track ids carry the run's number, the report is of this run's people; None: no
    record); it is begun first, so a second service on it is refused before anything is said on ``mqtt`` (a
    ``mqtt://HOST[:PORT]/PREFIX`` URL: events and occupancy published, ``live.mqtt.MqttPublisher``).
    ``offsets_s``: each camera's clock ahead of the first's. ``command``: the run as the store notes it.
    ``started(url)``: the page listens; ``said(line)``: what the run says as it begins (the store's run, people a
    run cut off left in view, the cameras on Ray, the page). Whatever ends the run, every output is complete and
    the store, MQTT, the streams and a Ray it started are closed."""
    out_dir = Path(out_dir)
    site = job.site_plan() if site is None else site
    recorder = start_record(job, store, command, site, options.start_time) if store is not None else None
    publisher = inputs = summary = None
    handlers = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)} if signals else {}
    try:
        publisher = MqttPublisher(mqtt, site or Site()) if mqtt else None
        inputs = streams(job, recorder=recorder)
        stop = stop or threading.Event()
        try:
            for line in _said_at_the_start(inputs, recorder, len(job.inputs)):
                said(line)
            caught = stop_on_signals(stop, inputs.followed) if signals else []
        except BaseException:  # the streams are open and not followed yet: let them go
            _let_go(inputs.followed)
            if inputs.ray is not None:
                inputs.ray.shutdown()
            raise

        def page(url: str) -> None:
            said(f"live page: {url}")
            started(url)

        summary = _followed_to_the_end(inputs, out_dir, site, options, stop, page, offsets_s, recorder, publisher,
                                       job.video.min_track_s)
    finally:
        if summary is None:  # it failed before its streams or while they were followed
            if recorder is not None and inputs is None:  # a run that never opened its streams is taken out
                recorder.discard()
            elif recorder is not None:  # one that did has its end noted (closing again does nothing)
                recorder.close("not started")
            if publisher is not None:
                publisher.close(wait_s=0.0)  # closing it again (once followed) does nothing
        for number, handler in handlers.items():  # the caller's own again, once the outputs are complete
            signal.signal(number, handler)
    return LiveRun(summary, recorder, publisher, caught[0] if caught else None)


def _said_at_the_start(inputs: LiveInputs, recorder: RunRecorder | None, cameras: int) -> list[str]:
    """What a run says once its streams are open: what is implausible of a camera (a ``warning:``, as the offline
    commands say after their work), its run of the store and the files it takes up, the people and visits a run
    cut off left open (ended now), the cameras on Ray."""
    lines = [f"warning: {doubt}" for camera in inputs.followed.cameras for doubt in camera.doubts()[1]]
    if recorder is not None:
        taken_up = [f"{r.source} at frame {r.first_index}" for r in recorder.resumes if r.first_index]
        lines.append(f"store {recorder.shown}: run {recorder.run}"
                     + (f", taking up {', '.join(taken_up)}" if taken_up else ""))
        if recorder.closed:
            tracks = sum(e["event"] == TRACK_ENDED.name for e in recorder.closed)
            lines.append(f"store {recorder.shown}: a run was cut off (killed): the {tracks} people it left in view "
                         f"and {len(recorder.closed) - tracks} zone visits of theirs ended at its last commit (\"the "
                         "service stopped\")")
    if inputs.on_ray:
        lines.append(f"on Ray ({inputs.address}): {cameras} camera actor(s), each reading and decoding its stream, "
                     "finding and lifting its people")
    return lines


def _let_go(followed) -> None:
    """Cameras whose streams are open but will not be followed: closed, their threads ended."""
    followed.close()
    followed.finish()


def _followed_to_the_end(inputs: LiveInputs, out_dir: Path, site: Site | None, options: LiveOptions,
                         stop: threading.Event, started, offsets_s: list[float] | None, recorder: RunRecorder | None,
                         mqtt: MqttPublisher | None, min_track_s: float) -> LiveSummary:
    """``inputs`` followed (``live.runner.follow``), then a Ray the job started stopped and the tail written
    (``_tail``); the fused world, where it would be written over, refused before the streams are followed."""
    ends_in = out_dir / f"run{recorder.run}" if recorder is not None and recorder.continues else out_dir
    try:
        if len(inputs.followed.cameras) > 1 and (ends_in / "world.json").exists():
            _let_go(inputs.followed)
            raise InputError(f"{ends_in / 'world.json'}: exists; ray3d live never writes over an output", ("out",))
        summary = follow(inputs.followed, out_dir, site, options, stop, started, offsets_s, recorder, mqtt,
                         min_track_s)
    finally:
        if inputs.ray is not None:
            inputs.ray.shutdown()
    _tail(summary, ends_in, site, options, offsets_s, recorder, inputs.followed.name)
    return summary


def _tail(summary: LiveSummary, ends_in: Path, site: Site | None, options: LiveOptions,
          offsets_s: list[float] | None, recorder: RunRecorder | None, name: str) -> None:
    """The tail of an offline job on this run's people (``this_run``): each camera's world file read once; several
    cameras' fused into ``ends_in``/world.json; the site's report of that world in ``ends_in``/site. The files
    and the number of people go into ``summary``."""
    paths = summary.files["worlds"]
    worlds = {k: world for k, path in enumerate(paths)
              if path.exists() and (world := this_run(read_world(path), recorder)) is not None}
    world = worlds.get(0) if len(paths) == 1 else _fused(worlds, summary.joined, offsets_s, ends_in / "world.json")
    if len(paths) > 1 and world is not None:
        summary.files["world"], summary.tracks = ends_in / "world.json", len(world.tracks)
    if world is None or site is None or not (site.zones or site.lines):
        return
    title = f"ray3d live: {name}" + (f", run {recorder.run} only" if recorder is not None else "")
    # A start time without time buckets placed the store's clock only: the report has nothing it places.
    folder = site_report(world, site, ends_in / "site", title, every_s=options.every_s,
                         start_time=options.start_time if options.every_s else None).folder
    if recorder is not None:
        write_text(folder / COVERS, covers(recorder, len(world.tracks)))
    summary.files["site"] = folder


def _fused(worlds: dict[int, World], joined: dict, offsets_s: list[float] | None, path: Path) -> World | None:
    """Several cameras' worlds ({camera index: world}) fused into one written to ``path``, by the join the live
    events used (``joined``: {person: [(camera index, track), ...]}); one camera's alone as it is; None without
    any."""
    if not worlds:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    if len(worlds) == 1:
        world = next(iter(worlds.values()))
        write_world(path, world)
        return world
    views = list(worlds)
    position = {k: i for i, k in enumerate(views)}
    groups = {person: [(position[view], track) for view, track in members if view in position]
              for person, members in joined.items()}
    offsets = [0.0] * len(views) if offsets_s is None else [offsets_s[k] - offsets_s[views[0]] for k in views]
    return fuse_and_write(list(worlds.values()), path, offsets, groups=groups).world


COVERS = "README.txt"  # in a run's site report: what it covers, and where the report over every run is


def this_run(world: World, recorder: RunRecorder | None) -> World | None:
    """The people of one run (``recorder``, a ``store.RunRecorder``) of a world file every run of a store appends to:
    their ids begin with the run's ``id_prefix``, or they were in view when the run before was cut off and this one
    took them up (``carried``); None where it has none. Without a store every person is the run's."""
    if recorder is None:
        return world
    carried = {person.person for person in recorder.carried}
    mine = {track: result for track, result in world.tracks.items()
            if track.startswith(recorder.id_prefix) or track in carried}
    return dataclasses.replace(world, tracks=mine) if mine else None


def covers(recorder, people: int) -> str:
    """What a run's site report covers, said beside it: its run only, and the store's report as the one over
    every run."""
    return (f"This report covers run {recorder.run} of the store {recorder.shown} only: its {people} people, from "
            "the world file (each person lifted again whole once they left, so its counts can differ a little from "
            "the live events').\n"
            "The record of every run is the store: its report is the one to count by,\n"
            f"    ray3d site --store {recorder.shown} --site SITE --out REPORT\n"
            "(SITE: the site file the runs followed; --from / --to for a period).\n")
