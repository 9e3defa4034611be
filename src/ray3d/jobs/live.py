"""A live job: its streams opened, each with its camera, detector and lifter (``open_live``: in this process, or
with ``address`` each camera in a Ray actor, ``live.cluster``), followed as they arrive (``live.runner.follow``),
and at the end the same tail as an offline job: several cameras' world files fused into one
(``jobs.run.fuse_and_write``) and, with a site, its report (``jobs.run.site_report``)."""

from __future__ import annotations

import dataclasses
import functools
import threading
from pathlib import Path

from ray3d.io.atomic import write_text
from ray3d.jobs.job import Job
from ray3d.jobs.run import camera_and_detector, fuse_and_write, site_report


@dataclasses.dataclass
class LiveInputs:
    """A live job's cameras following their streams (``live.cameras.LocalCameras`` or ``live.cluster.RayCameras``:
    ``followed``), and the Ray this job started, to stop at its end (None: none started)."""

    followed: object
    ray: object = None

    @property
    def on_ray(self) -> bool:
        from ray3d.live.cluster import RayCameras

        return isinstance(self.followed, RayCameras)


def local_inputs(job: Job, group, cameras: list, detectors: list, id_prefix: str = "", carried=()) -> LiveInputs:
    """Streams already open (a ``SourceGroup``), with a camera and a detector each, followed in this process by the
    job's lifter (``id_prefix`` before every track id: a store's run number; ``carried``: the people in view when
    the store's run before was cut off, ``RunRecorder.carried``)."""
    from ray3d.live.cameras import LocalCameras

    options = [job.lift_options(k) for k in range(len(cameras))]  # each camera on its own floor, as on Ray
    return LiveInputs(LocalCameras(group, cameras, detectors, job.lifter(detectors[0].layout), options,
                                   job.video.max_gap_s, job.video.min_track_s, id_prefix, carried))


def start_record(job: Job, store, command: str, site=None, start_time=None):
    """The store's record of this run begun (``store.RunRecorder``: ``store`` a file, SQLite, or a
    ``postgresql://`` URL): the run numbered, the gaps since the last one, where each file input is taken up.
    ``start_time`` (a ``datetime``): the wall-clock time of the inputs' frame 0 (default: now, or the clock of the
    run that began a file taken up)."""
    from ray3d.store import RunRecorder

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
    import sys

    from ray3d.live.reconnect import ReconnectingSource
    from ray3d.live.source import FrameSource
    from ray3d.video import VideoInfo

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
        from ray3d.jobs.cluster import start_ray
        from ray3d.live.cluster import RayCameras

        ray, started = start_ray(address, workers, "live jobs on a cluster")
        arguments = [dict(opened=functools.partial(open_stream, job, k, paced, stall_timeout_s,
                                                   reconnect_max_s=reconnect_max_s),
                          lifter=job.lifter, lift_options=job.lift_options(k), first_index=firsts[k],
                          id_prefix=prefix, max_gap_s=job.video.max_gap_s, min_track_s=job.video.min_track_s,
                          carried=carried)
                     for k in range(len(job.inputs))]
        played = [paced is not False] * len(job.inputs)  # an unpaced file waits for its reader; the rest play on
        try:
            return LiveInputs(RayCameras(ray, arguments, [str(s) for s in job.inputs], played, cpus_per_camera),
                              ray if started else None)
        except BaseException:
            if started:
                ray.shutdown()
            raise
    from ray3d.live.source import SourceGroup

    opened = [open_stream(job, k, paced, stall_timeout_s, firsts[k], reconnect_max_s) for k in range(len(job.inputs))]
    detectors = [detector for _, _, detector in opened]
    return local_inputs(job, SourceGroup([source for source, _, _ in opened]), [camera for _, camera, _ in opened],
                        detectors, prefix, carried)


def run_live_job(job: Job, inputs: LiveInputs, out_dir: str | Path, site=None, options=None,
                 stop: threading.Event | None = None, started=lambda url: None,
                 offsets_s: list[float] | None = None, recorder=None, mqtt=None):
    """Follow ``inputs`` (``open_live``) until they end, stall, break off or ``stop`` is set (``live.runner.follow``:
    with the store's ``recorder`` and ``mqtt``, a ``live.mqtt.MqttPublisher``); then fuse several cameras' world
    files into ``out_dir``/world.json and write the site's report in ``out_dir``/site (a run continuing a store's
    record: in ``out_dir``/run<N>/, nothing written before is replaced). With a ``recorder`` the report is of this
    run's people only, and its ``COVERS`` file says so and names the store's report, the one over every run.
    Returns the ``LiveSummary``, its ``files`` naming every output."""
    from ray3d.io.world import read_world, write_world
    from ray3d.live.runner import LiveOptions, follow
    from ray3d.live.views import JOINED_FILE, read_joined

    out_dir = Path(out_dir)
    several = len(inputs.followed.cameras) > 1
    ends_in = out_dir / f"run{recorder.run}" if recorder is not None and recorder.continues else out_dir
    fused_path = ends_in / "world.json"
    try:
        if several and fused_path.exists():  # refused before the stream, not after it
            from ray3d.errors import InputError

            inputs.followed.close()
            inputs.followed.finish()
            raise InputError(f"{fused_path}: exists; ray3d live never writes over an output", ("out",))
        options = options or LiveOptions()
        summary = follow(inputs.followed, out_dir, site, options, stop, started, offsets_s, recorder, mqtt)
    finally:
        if inputs.ray is not None:
            inputs.ray.shutdown()
    written = [(path, k) for k, path in enumerate(summary.files["worlds"]) if path.exists()]
    if several and written:
        offsets = offsets_s or [0.0] * len(inputs.followed.cameras)
        worlds = [read_world(path) for path, _ in written]
        ends_in.mkdir(parents=True, exist_ok=True)
        if len(worlds) == 1:
            write_world(fused_path, worlds[0])
            summary.tracks = len(worlds[0].tracks)
        else:  # fused by the join the live events used
            position = {k: i for i, (_, k) in enumerate(written)}
            groups = {person: [(position[view], track) for view, track in members if view in position]
                      for person, members in read_joined(out_dir / JOINED_FILE).items()}
            fusion = fuse_and_write(worlds, fused_path, [offsets[k] - offsets[written[0][1]] for _, k in written],
                                    groups=groups)
            summary.tracks = len(fusion.world.tracks)  # the world's people, not each camera's tracks
        summary.files["world"] = fused_path
    if site is not None and (site.zones or site.lines) and summary.files["world"].exists():
        world = read_world(summary.files["world"])
        if recorder is None:
            summary.files["site"] = site_report(world, site, ends_in / "site", f"ray3d live: {inputs.followed.name}",
                                                every_s=options.every_s, start_time=options.start_time).folder
        elif (world := this_run(world, recorder)) is not None:
            folder = site_report(world, site, ends_in / "site", f"ray3d live: {inputs.followed.name}, run "
                                 f"{recorder.run} only", every_s=options.every_s,
                                 start_time=options.start_time).folder
            write_text(folder / COVERS, covers(recorder, len(world.tracks)))
            summary.files["site"] = folder
    return summary


COVERS = "README.txt"  # in a run's site report: what it covers, and where the report over every run is


def this_run(world, recorder):
    """The people of one run (``recorder``, a ``store.RunRecorder``) of a world file every run of a store appends to:
    their ids begin with the run's ``id_prefix``, or they were in view when the run before was cut off and this one
    took them up (``carried``); None where it has none."""
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
