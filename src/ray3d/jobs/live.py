"""A live job: its streams opened, each with its camera and detector (``open_live``), followed as they arrive
(``ray3d.live.run_live``), and at the end the same tail as an offline job: several cameras' world files fused
into one (``jobs.run.fuse_and_write``) and, with a site, its report (``ray3d.site.report``)."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

from ray3d.jobs.job import Job
from ray3d.jobs.run import fuse_and_write


@dataclasses.dataclass
class LiveInputs:
    """A live job's streams made ready: their ``SourceGroup``, and per stream its camera and detector; the
    ``lifter`` (None: the shipped model for the detectors' layout)."""

    group: object
    cameras: list
    detectors: list
    lifter: object


def open_live(job: Job, paced: bool | None = None, stall_timeout_s: float = 10.0) -> LiveInputs:
    """Open every input of ``job`` as a stream (a file, a device number, a URL; ``paced``: played at its own rate,
    the default for files), its camera for the stream's image size and a detector that keeps up."""
    from ray3d.live.source import FrameSource, SourceGroup
    from ray3d.video import DEFAULT_DETECTOR, VideoInfo, camera_for_video, make_detector

    sources = [FrameSource.open(source, job.video.fps, paced, stall_timeout_s) for source in job.inputs]
    cameras = [camera_for_video(choice.camera(s.image_size), VideoInfo(s.name, 0, s.fps, s.image_size))
               for s, choice in zip(sources, job.cameras)]
    detectors = [make_detector(job.detector or DEFAULT_DETECTOR, camera, live=True) for camera in cameras]
    for detector in detectors:
        detector.prepare([])
    return LiveInputs(SourceGroup(sources), cameras, detectors, job.lifter(detectors[0].layout))


def run_live_job(job: Job, inputs: LiveInputs, out_dir: str | Path, site=None, options=None,
                 stop: threading.Event | None = None, started=lambda url: None,
                 offsets_s: list[float] | None = None):
    """Follow ``inputs`` (``open_live``) until they end, stall, break off or ``stop`` is set (``live.run_live``);
    then fuse several cameras' world files into ``out_dir``/world.json and write the site's report in
    ``out_dir``/site. Returns the ``LiveSummary``, its ``files`` naming every output."""
    from ray3d.io.world import read_world
    from ray3d.live.runner import LiveOptions, run_live

    out_dir = Path(out_dir)
    several = len(inputs.cameras) > 1
    fused_path = out_dir / "world.json"
    if several and fused_path.exists():  # refused before the stream, not after it
        from ray3d.errors import InputError

        raise InputError(f"{fused_path}: exists; ray3d live never writes over an output", ("out",))
    summary = run_live(inputs.group, inputs.cameras if several else inputs.cameras[0], out_dir,
                       inputs.detectors if several else inputs.detectors[0], inputs.lifter, site,
                       options or LiveOptions(), job.lift_options(0), stop, started, offsets_s)
    written = [(path, k) for k, path in enumerate(summary.files["worlds"]) if path.exists()]
    if several and written:
        offsets = offsets_s or [0.0] * len(inputs.cameras)
        worlds = [read_world(path) for path, _ in written]
        if len(worlds) == 1:
            from ray3d.io.world import write_world

            write_world(fused_path, worlds[0])
        else:
            fuse_and_write(worlds, fused_path, [offsets[k] - offsets[written[0][1]] for _, k in written])
        summary.files["world"] = fused_path
    if site is not None and (site.zones or site.lines) and summary.files["world"].exists():
        from ray3d.site.report import analyse_site

        analyse_site(read_world(summary.files["world"]), site, out_dir / "site",
                     title=f"ray3d live: {inputs.group.name}")
        summary.files["site"] = out_dir / "site"
    return summary
