"""Running a job: each input lifted as one camera's (``run_input``: a keypoint file by ``lift_file``, a video by
its detector, its tracker and ``lift_video``), and several cameras' worlds fused into one and written with its
viewer (``fuse_and_write``). The one place that assembles a video's camera, detector and lifter
(``video_input``) and the one that fuses worlds; the command line, batch tasks, live and the benchmarks run
their inputs through it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ray3d.geometry import Camera
from ray3d.io.bvh_export import export_paths
from ray3d.io.world import World, write_world
from ray3d.jobs.job import Job


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


def video_input(job: Job, k: int):
    """Input ``k`` of a video job made ready: its ``VideoInfo`` (the header read once), its camera (for the video's
    image size) and its detector."""
    from ray3d.video import read_video_info

    info = read_video_info(job.inputs[k])
    return (info, *camera_and_detector(job, k, info))


def camera_and_detector(job: Job, k: int, info, live: bool = False):
    """Input ``k``'s camera for its video's or stream's ``VideoInfo`` (image size, frame rate) and its detector
    (``live``: one that keeps up with a stream; a callable ``job.detector`` makes it for the camera). The one place
    a video's or a stream's camera and detector are put together."""
    from ray3d.video import DEFAULT_DETECTOR, camera_for_video, make_detector

    camera = camera_for_video(job.cameras[k].camera(info.image_size), info)
    detector = job.detector(camera) if callable(job.detector) else \
        make_detector(job.detector or DEFAULT_DETECTOR, camera, live=live)
    return camera, detector


def run_input(job: Job, k: int, out: str | Path | None, progress: bool = True) -> InputResult:
    """Input ``k`` lifted as one camera's: a video into the folder ``out`` (world, detections, viewer, overlay), a
    keypoint file into the world file ``out`` (None: lifted, not written)."""
    from ray3d.lifting.files import lift_file

    if job.kind == "video":
        from ray3d.video import lift_video

        info, camera, detector = video_input(job, k)
        result = lift_video(info, camera, out, detector, job.lifter(detector.layout), job.lift_options(k), job.video,
                            world_format=job.world_format, overlay=job.overlay, overwrite=job.overwrite,
                            progress=progress)
        return InputResult(result.world, camera, result.frames, result.files, video=result)
    camera = job.cameras[k].camera()
    keypoints, world = lift_file(job.inputs[k], camera, out, job.lifter(job.layout, job.inputs[k]), job.layout,
                                 job.fps, job.overwrite, job.read_options, job.lift_options(k), progress)
    written = [] if out is None else list(dict.fromkeys(export_paths(out, world).values()))  # BVH: one per track
    files = {"world": written[0]} if len(written) == 1 else {f"world {path.stem}": path for path in written}
    frames = len({int(f) for result in world.tracks.values() for f in result.frames})
    return InputResult(world.in_frame("world"), camera, frames, files, keypoints=keypoints)


def run_videos_together(job: Job, outs: list[str | Path], progress: bool = True) -> list[InputResult]:
    """Every video of a several-camera job into its folder of ``outs``, its people followed as ``run_input``
    follows them and lifted with every other camera's on the site's one floor (``video.lift_videos``)."""
    from ray3d.video import lift_videos

    opened = [video_input(job, k) for k in range(len(job.inputs))]
    results = lift_videos([(info, camera, out, detector) for (info, camera, detector), out in zip(opened, outs)],
                          job.lifter(opened[0][2].layout), job.lift_options(0), job.video, job.world_format,
                          job.overlay, job.overwrite, progress, one_clock=not job.find_offsets)
    return [InputResult(result.world, camera, result.frames, result.files, video=result)
            for result, (_, camera, _) in zip(results, opened)]


def lift_cameras_together(job: Job, progress: bool = True) -> list[InputResult]:
    """Every keypoint file of a several-camera job lifted as one site's cameras (``Lifter.lift_cameras``): one
    world frame, one floor, where people's ankles meet it observed from every camera's people together (and
    triangulated where two see one at once, unless the files' clocks are to be found). Not written; fuse them with
    ``fuse_and_write``."""
    from ray3d.errors import InputError
    from ray3d.io.keypoints import read_keypoints
    from ray3d.lifting.lifter import Lifter

    files = [read_keypoints(path, job.layout, job.fps, **job.read_options) for path in job.inputs]
    cameras = [choice.camera() for choice in job.cameras]
    layouts = {k: keypoints.layout for k, keypoints in enumerate(files)}
    lifter = job.lifter(files[0].layout) or Lifter.load(layout=files[0].layout)
    lifted = lifter.lift_cameras({k: (keypoints.by_track(), camera) for k, (keypoints, camera)
                                  in enumerate(zip(files, cameras))}, layouts,
                                 {k: keypoints.fps for k, keypoints in enumerate(files)}, progress,
                                 one_clock=not job.find_offsets, **job.lift_options(0).lift_arguments())
    results = []
    for k, (path, keypoints, camera) in enumerate(zip(job.inputs, files, cameras)):
        if isinstance(lifted[k], InputError):
            raise InputError(f"{path}: {lifted[k].message}", lifted[k].arguments)
        world = World(lifted[k], camera, lifter.name, unliftable=lifted[k].unliftable)
        frames = len({int(f) for result in world.tracks.values() for f in result.frames})
        results.append(InputResult(world, camera, frames, {}, keypoints=keypoints))
    return results


def fuse_and_write(worlds: list[World], world_path: str | Path | None = None, offsets_s: list[float] | None = None,
                   find_offsets: bool = False, max_offset_s: float = 2.0, handover_s: float = 2.0,
                   viewer_path: str | Path | None = None, title: str = "", overwrite: bool = False):
    """Several cameras' worlds -> one (``ray3d.fusion.fuse_worlds``: offsets given, found, or 0), written to
    ``world_path`` (.json) and drawn in ``viewer_path`` where given. Returns the ``Fusion``."""
    from ray3d.fusion import fuse_worlds
    from ray3d.io.atomic import refuse_existing

    for path in (world_path, viewer_path):
        if path is not None:
            refuse_existing(Path(path), overwrite)
    fusion = fuse_worlds(worlds, offsets_s, find_offsets, max_offset_s, handover_s)
    if world_path is not None:
        write_world(world_path, fusion.world, overwrite=overwrite)
    if viewer_path is not None:
        from ray3d.viz.html_viewer import write_viewer

        write_viewer(viewer_path, fusion.world.tracks, fusion.world.fps, fusion.world.camera,
                     title=title or f"ray3d: {len(worlds)} cameras", overwrite=overwrite,
                     more_cameras=fusion.world.cameras[1:])
    return fusion
