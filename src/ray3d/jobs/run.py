"""Running a job: the whole of it (``run_job``: every input lifted, several cameras fused, the outputs and the
site's report written), each input lifted as one camera's (``run_input``: a keypoint file by ``lift_file``, a video
by its detector, its tracker and ``lift_video``), several cameras' worlds fused into one and written with its
viewer (``fuse_and_write``), and a world's report on a site (``site_report``). The one place that assembles a
video's camera, detector and lifter (``video_input``), the one that fuses worlds and the one that reports on a
site; the command line, batch tasks, live and the benchmarks run their jobs through it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ray3d.errors import InputError
from ray3d.fusion import fuse_worlds
from ray3d.geometry import Camera
from ray3d.io.atomic import check_output, refuse_existing
from ray3d.io.bvh_export import export_paths
from ray3d.io.keypoints import read_keypoints
from ray3d.io.world import World, write_world
from ray3d.jobs.job import Job
from ray3d.lifting.files import lift_file
from ray3d.site.places import Site
from ray3d.site.report import analyse_site, site_outputs
from ray3d.video import DEFAULT_DETECTOR, camera_for_video, lift_video, lift_videos, make_detector, read_video_info
from ray3d.viz.html_viewer import write_viewer


@dataclasses.dataclass
class InputResult:
    """What one input gave: its world (every track, in the world frame), the camera it was lifted through, the
    frames it spans, the files written ({role: path}) and what was read (a video's ``VideoResult``, a keypoint
    file's ``Keypoints``)."""

    world: World
    camera: Camera
    frames: int
    files: dict[str, Path]
    video: object = None
    keypoints: object = None


@dataclasses.dataclass
class SiteReport:
    """A world's report on a site (``site.report.analyse_site``): its events, a row per zone and line (``places``)
    and the files written in ``folder``."""

    events: list[dict]
    places: list[dict]
    files: list[Path]
    folder: Path


@dataclasses.dataclass
class JobResult:
    """What a whole job gave: each input's ``InputResult``, the job's ``world`` (the one input's, or the cameras'
    fused), the ``fusion`` (several cameras), the ``site`` report (a job with a site) and every file written
    ({role: path}) and ``notes``, what the user should know that did not stop it."""

    inputs: list[InputResult]
    world: World
    files: dict[str, Path]
    fusion: object = None
    site: SiteReport | None = None
    notes: list[str] = dataclasses.field(default_factory=list)  # what the user should know that did not stop it


def run_job(job: Job, out: str | Path, progress: bool = True) -> JobResult:
    """The whole of ``job``: every input lifted (several cameras of one site together, on one floor), several
    cameras' worlds fused, and with a site its report. ``out``: a video job's folder (several videos: each camera's
    outputs in ``out``/camera<k>_<name>/, the fused world.json and viewer.html in ``out``); a keypoint job's world
    file (several files: the fused .json). The site's report goes to ``site_folder(job, out)``. Every output is
    refused before any work where it exists (unless ``job.overwrite``) or is an input."""
    if not isinstance(out, (str, Path)):
        raise InputError(f"out: a folder (videos) or a world file (keypoints); got {type(out).__name__}", ("out",))
    out = Path(out)
    several = len(job.inputs) > 1
    fused = _fused_outputs(job, out) if several else {}
    for path in fused.values():
        refuse_existing(check_output(path, (*job.inputs, *(c.file for c in job.cameras if c.file))), job.overwrite)
    if job.site is not None:
        check_site_outputs(site_folder(job, out), (*job.inputs, job.site), job.overwrite, job.every_s)
    if job.kind == "video":
        results = run_videos_together(job, [out / f"camera{k + 1}_{Path(path).stem}" for k, path
                                            in enumerate(job.inputs)], progress) if several \
            else [run_input(job, 0, out, progress)]
    else:
        results = lift_cameras_together(job, progress) if several else [run_input(job, 0, out, progress)]
    done = JobResult(results, results[0].world, dict(results[0].files) if not several else dict(fused))
    for k, result in enumerate(results):
        try:
            job.remember_floor_seen(k, result.world.floor_evidence)
        except OSError as err:  # a camera file in a folder it may not write: the job's outputs still stand
            done.notes.append(f"{job.floor_memory(k)}: could not keep what this run's people showed of the floor "
                              f"({err.strerror or err}); the next run will not weigh it in")
    if several:
        done.fusion = fuse_and_write([r.world for r in results], fused["world"], find_offsets=job.find_offsets,
                                     viewer_path=fused.get("viewer"), overwrite=job.overwrite)
        done.world = done.fusion.world
    if job.site is not None:
        name = f"{len(job.inputs)} cameras" if several else Path(job.inputs[0]).name
        done.site = site_report(done.world, job.site_plan(), site_folder(job, out), f"{name} on {job.site.name}",
                                job.overwrite, job.every_s, job.start_time)
        done.files["site"] = done.site.folder
    return done


def _fused_outputs(job: Job, out: Path) -> dict[str, Path]:
    """Where several cameras' fused world (and a video job's viewer) go."""
    if job.kind == "video":
        if job.world_format != ".json":
            raise InputError("format: several cameras' people are fused into a .json world file", ("format",))
        return {"world": out / "world.json", "viewer": out / "viewer.html"}
    if out.suffix.lower() != ".json":
        raise InputError(f"{out}: several cameras' people are fused into a .json world file", ("out",))
    return {"world": out}


def site_folder(job: Job, out: str | Path) -> Path:
    """Where ``run_job`` writes the site's report: ``out``/site for a video job, beside the world file for a
    keypoint job."""
    return Path(out) / "site" if job.kind == "video" else Path(out).parent / "site"


def check_site_outputs(folder: Path, inputs: tuple, overwrite: bool, every_s: float | None = None) -> None:
    """Before any work: no output of a site's report in ``folder`` (with time buckets of ``every_s``) may be one of
    ``inputs`` or exist (unless ``overwrite``)."""
    for path in site_outputs(folder, every_s is not None):
        refuse_existing(check_output(path, inputs), overwrite)


def site_report(world: World, site, folder: str | Path, title: str = "", overwrite: bool = False,
                every_s: float | None = None, start_time=None) -> SiteReport:
    """``world``'s people on ``site`` (a ``site.places.Site``): its events, counts per place, tables and plots in
    ``folder`` (``site.report.analyse_site``; time buckets of ``every_s`` seconds from ``start_time``). The one
    place a job's, a live run's or ``ray3d site``'s report is made."""
    if not isinstance(world, World) or not isinstance(site, Site):
        raise InputError(f"world, site: a World and a Site (site.files.read_site); got {type(world).__name__} and "
                         f"{type(site).__name__}", ("world", "site"))
    if start_time is not None and every_s is None:
        raise InputError("start_time places the time buckets: give every_s too", ("start_time", "every_s"))
    events, places, files = analyse_site(world, site, folder, title, overwrite, every_s, start_time)
    return SiteReport(events, places, files, Path(folder))


def video_input(job: Job, k: int):
    """Input ``k`` of a video job made ready: its ``VideoInfo`` (the header read once), its camera (for the video's
    image size) and its detector."""
    info = read_video_info(job.inputs[k])
    return (info, *camera_and_detector(job, k, info))


def camera_and_detector(job: Job, k: int, info, live: bool = False):
    """Input ``k``'s camera for its video's or stream's ``VideoInfo`` (image size, frame rate) and its detector
    (``live``: one that keeps up with a stream; a callable ``job.detector`` makes it for the camera). The one place
    a video's or a stream's camera and detector are put together."""
    camera = camera_for_video(job.cameras[k].camera(info.image_size), info)
    detector = job.detector(camera) if callable(job.detector) else \
        make_detector(job.detector or DEFAULT_DETECTOR, camera, live=live)
    return camera, detector


def run_input(job: Job, k: int, out: str | Path | None, progress: bool = True) -> InputResult:
    """Input ``k`` lifted as one camera's: a video into the folder ``out`` (world, detections, viewer, overlay), a
    keypoint file into the world file ``out`` (None: lifted, not written)."""
    if job.kind == "video":
        info, camera, detector = video_input(job, k)
        result = lift_video(info, camera, out, detector, job.lifter(detector.layout), job.lift_options(k), job.video,
                            world_format=job.world_format, overlay=job.overlay, overwrite=job.overwrite,
                            progress=progress)
        return InputResult(result.world, camera, result.frames, result.files, video=result)
    camera = job.cameras[k].camera()
    keypoints, world = lift_file(job.inputs[k], camera, out, job.lifter, job.layout,
                                 job.fps, job.overwrite, job.read_options, job.lift_options(k), progress)
    written = [] if out is None else list(dict.fromkeys(export_paths(out, world).values()))  # BVH: one per track
    files = {"world": written[0]} if len(written) == 1 else {f"world {path.stem}": path for path in written}
    frames = len({int(f) for result in world.tracks.values() for f in result.frames})
    return InputResult(world.in_frame("world"), camera, frames, files, keypoints=keypoints)


def run_videos_together(job: Job, outs: list[str | Path], progress: bool = True) -> list[InputResult]:
    """Every video of a several-camera job into its folder of ``outs``, its people followed as ``run_input``
    follows them and lifted with every other camera's on the site's one floor (``video.lift_videos``)."""
    opened = [video_input(job, k) for k in range(len(job.inputs))]
    results = lift_videos([(info, camera, out, detector) for (info, camera, detector), out in zip(opened, outs)],
                          job.lifter(opened[0][2].layout), [job.lift_options(k) for k in range(len(opened))],
                          job.video, job.world_format, job.overlay, job.overwrite, progress,
                          one_clock=not job.find_offsets)
    return [InputResult(result.world, camera, result.frames, result.files, video=result)
            for result, (_, camera, _) in zip(results, opened)]


def lift_cameras_together(job: Job, progress: bool = True) -> list[InputResult]:
    """Every keypoint file of a several-camera job lifted as one site's cameras (``Lifter.lift_cameras``): one
    world frame, one floor, where people's ankles meet it observed from every camera's people together (and
    triangulated where two see one at once, unless the files' clocks are to be found). Not written; fuse them with
    ``fuse_and_write``."""
    options = {k: job.lift_options(k) for k in range(len(job.inputs))}  # each camera's own, as live's
    files = [read_keypoints(path, job.layout, job.fps, **job.read_options) for path in job.inputs]
    cameras = [choice.camera() for choice in job.cameras]
    layouts = {k: keypoints.layout for k, keypoints in enumerate(files)}
    lifter = job.lifter(files[0].layout)
    lifted = lifter.lift_cameras({k: (keypoints.by_track(), camera) for k, (keypoints, camera)
                                  in enumerate(zip(files, cameras))}, layouts,
                                 {k: keypoints.fps for k, keypoints in enumerate(files)}, progress,
                                 one_clock=not job.find_offsets, options=options)
    results = []
    for k, (path, keypoints, camera) in enumerate(zip(job.inputs, files, cameras)):
        if isinstance(lifted[k], InputError):
            raise InputError(f"{path}: {lifted[k].message}", lifted[k].arguments)
        world = World(lifted[k], camera, lifter.name, unliftable=lifted[k].unliftable,
                      floor_evidence=lifted[k].floor_evidence())
        frames = len({int(f) for result in world.tracks.values() for f in result.frames})
        results.append(InputResult(world, camera, frames, {}, keypoints=keypoints))
    return results


def fuse_and_write(worlds: list[World], world_path: str | Path | None = None, offsets_s: list[float] | None = None,
                   find_offsets: bool = False, max_offset_s: float = 2.0, handover_s: float = 2.0,
                   viewer_path: str | Path | None = None, title: str = "", overwrite: bool = False,
                   groups: dict | None = None):
    """Several cameras' worlds -> one (``ray3d.fusion.fuse_worlds``: offsets given, found, or 0; who is who found,
    or given as ``groups``), written to ``world_path`` (.json) and drawn in ``viewer_path`` where given. Returns
    the ``Fusion``."""
    for path in (world_path, viewer_path):
        if path is not None:
            refuse_existing(Path(path), overwrite)
    fusion = fuse_worlds(worlds, offsets_s, find_offsets, max_offset_s, handover_s, groups)
    if world_path is not None:
        write_world(world_path, fusion.world, overwrite=overwrite)
    if viewer_path is not None:
        write_viewer(viewer_path, fusion.world.tracks, fusion.world.fps, fusion.world.camera,
                     title=title or f"ray3d: {len(worlds)} cameras", overwrite=overwrite,
                     more_cameras=fusion.world.cameras[1:])
    return fusion
