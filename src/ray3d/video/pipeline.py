"""``lift_video``: frames (OpenCV, streamed) -> the people in each frame -> tracks -> world joints of every
track -> the world file, the detections (to re-lift without detecting again), the HTML viewer and an overlay
video (each person's detections and lifted joints projected back through the camera, with their id).

Frames are read one at a time and never kept: memory holds the detections (a few hundred bytes per person
and frame) and the tracker's state, not the video."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ray3d.checkpoints import VIDEO_MODEL
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.keypoints import Keypoints, write_keypoints_json
from ray3d.io.world import World, check_world_output, export_paths, write_world
from ray3d.lift import Lifter
from ray3d.temporal import OUTPUT_SMOOTHING, check_frame_rate
from ray3d.video.detectors import PoseDetector
from ray3d.video.frames import VideoInfo, read_frames, read_video_info, spread_frames
from ray3d.video.overlay import write_overlay
from ray3d.video.tracking import FloorTracker
from ray3d.viz.html_viewer import write_viewer

@dataclasses.dataclass
class VideoResult:
    """The tracked detections (every track, in the detector's layout), the lifted world, the frames read, the
    tracks dropped (too short, or not liftable: {track id: why}), the files written ({"world", "keypoints",
    "viewer", "overlay"}; a BVH world of several tracks is one file each: "world TRACK") and the seconds each
    stage took (people: reading, detecting and tracking; lifting; writing)."""

    keypoints: Keypoints
    world: World
    frames: int
    dropped: dict[int, str]
    files: dict[str, Path]
    seconds: dict[str, float]


def _span(info: VideoInfo, start: int, frames: int | None) -> int:
    """How many frames to read from ``start``, checked against the video."""
    if start < 0 or (info.frames > 0 and start >= info.frames):
        raise InputError(f"{info.path}: start frame {start} is outside its {info.frames} frames", arguments=("start",))
    if frames is not None and frames < 1:
        raise InputError(f"{info.path}: frames must be at least 1, got {frames}", arguments=("frames",))
    left = info.frames - start if info.frames > 0 else None
    return min(frames, left) if frames is not None and left is not None else (frames or left or 0)


def track_video(path: str | Path, camera: Camera, detector: PoseDetector, fps: float | None = None, start: int = 0,
                frames: int | None = None, max_gap_s: float = 0.5, min_track_s: float = 1.0,
                progress: bool = True) -> tuple[Keypoints, int, dict[int, str]]:
    """Detect and track everybody: (the tracks' detections as ``Keypoints`` at the video's frame index, the
    frames read, {track id: why it was dropped} for tracks shorter than ``min_track_s``)."""
    info = read_video_info(path)
    fps = _frame_rate(info, fps)
    for name, value in (("max_gap_s", max_gap_s), ("min_track_s", min_track_s)):
        if not np.isfinite(value) or value < 0:
            raise InputError(f"{name} must be a duration in seconds, 0 or more; got {value}", arguments=(name,))
    count = _span(info, start, frames)
    detector.prepare(spread_frames(info, start, count) if count else [])
    tracker = FloorTracker(camera, fps, detector.layout, max_gap_s)
    read = 0
    for index, frame in tqdm(read_frames(info.path, start, count or None), total=count or None, desc="people",
                             unit="frame", disable=not progress):
        tracker.update(index, detector(frame), frame)
        read += 1
    if read == 0:
        raise InputError(f"{info.path}: no frames could be read")
    kept, dropped = [], {}
    for track in tracker.tracks():
        seconds = (track.frames[-1] - track.frames[0] + 1) / fps
        if seconds < min_track_s:
            dropped[track.id] = f"seen for {seconds:.2f} s (under {min_track_s} s)"
        else:
            kept.append(track)
    if not kept:
        raise InputError(f"{info.path}: nobody was found and followed for {min_track_s} s in its {read} frame(s)")
    rows = [(t.id, f, d) for t in kept for f, d in zip(t.frames, t.detections)]
    keypoints = Keypoints(np.stack([d.pixels for _, _, d in rows]), np.stack([d.confidences for _, _, d in rows]),
                          np.array([f for _, f, _ in rows]), np.array([t for t, _, _ in rows]), detector.layout, fps,
                          f"{detector.layout} detections", info.path)
    return keypoints, read, dropped


def _frame_rate(info: VideoInfo, fps: float | None) -> float:
    """The frame rate given, checked, or else the video's own."""
    if fps is not None:
        return check_frame_rate(fps, str(info.path))
    if not info.fps > 0:
        raise InputError(f"{info.path}: the video reports no frame rate; give it", arguments=("fps",))
    return float(info.fps)


def _targets(out_dir: Path, world_format: str, overlay: bool, overwrite: bool) -> dict[str, Path]:
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder", arguments=("out",))
    if out_dir.is_dir() and any(out_dir.iterdir()) and not overwrite:
        raise InputError(f"{out_dir}: the output folder exists and is not empty; refusing to write into it",
                         arguments=("overwrite",))
    return {"world": out_dir / f"world{world_format}", "keypoints": out_dir / "keypoints.json",
            "viewer": out_dir / "viewer.html", **({"overlay": out_dir / "overlay.mp4"} if overlay else {})}


def lift_video(path: str | Path, camera: Camera, out_dir: str | Path, detector: PoseDetector,
               lifter: Lifter | None = None, fps: float | None = None, world_format: str = ".json",
               overlay: bool = True, overwrite: bool = False, progress: bool = True, start: int = 0,
               frames: int | None = None, max_gap_s: float = 0.5, min_track_s: float = 1.0,
               smooth_3d: str | None = OUTPUT_SMOOTHING, frame: str = "world",
               **lift_options) -> VideoResult:
    """Detect, track and lift everybody, and write ``out_dir``/{world.json|.csv|.npz, keypoints.json,
    viewer.html, overlay.mp4}.

    ``camera`` must have the video's image size; ``fps`` overrides the frame rate the video reports;
    ``start`` / ``frames`` select part of the video; a person unseen for longer than ``max_gap_s`` starts a
    new track, and tracks shorter than ``min_track_s`` are dropped. The lifted joints are smoothed in time
    (``smooth_3d``, Savitzky-Golay by default: it removes a detector's jitter without lag; None keeps them as
    lifted). The world file holds the joints in ``frame`` ("world" or "camera", see ``World.in_frame``); the
    viewer and overlay draw the world. ``lift_options`` go to ``Lifter.lift``.
    """
    info = read_video_info(path)
    if tuple(camera.image_size) != info.image_size:
        raise InputError(f"camera {camera.name or ''}: image size {tuple(camera.image_size)} but {info.path} is "
                         f"{info.image_size[0]}x{info.image_size[1]}")
    targets = _targets(Path(out_dir), world_format, overlay, overwrite)
    check_world_output(targets["world"], frame)
    clock = [time.perf_counter()]
    keypoints, read, dropped = track_video(info.path, camera, detector, fps, start, frames, max_gap_s, min_track_s,
                                           progress)
    clock.append(time.perf_counter())
    lifter = lifter or Lifter.load(VIDEO_MODEL)
    lifted = {}
    for track, entry in keypoints.by_track().items():
        try:
            lifted.update(lifter.lift_tracks({track: entry}, camera, keypoints.layout, keypoints.fps,
                                             smooth_3d=smooth_3d, **lift_options))
        except InputError as err:
            dropped[track] = err.message
    if not lifted:
        raise InputError(f"{info.path}: no track could be lifted: " + "; ".join(f"{t}: {w}" for t, w in dropped.items()))
    world = World(lifted, camera, lifter.name)
    clock.append(time.perf_counter())
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    write_world(targets["world"], world.in_frame(frame), overwrite=overwrite)
    write_keypoints_json(targets["keypoints"], keypoints, overwrite)
    write_viewer(targets["viewer"], world.tracks, keypoints.fps, camera, title=f"ray3d: {info.path.name}",
                 overwrite=overwrite)
    if overlay:
        write_overlay(info.path, targets["overlay"], keypoints, world, start, read, overwrite, progress)
    clock.append(time.perf_counter())
    seconds = dict(zip(("people", "lifting", "writing"), np.diff(clock).tolist()))
    worlds = dict.fromkeys(export_paths(targets["world"], world).values())  # BVH: one file per track
    files = {**targets, "world": next(iter(worlds))} if len(worlds) == 1 else \
        {**{f"world {p.stem.removeprefix('world_')}": p for p in worlds},
         **{k: v for k, v in targets.items() if k != "world"}}
    return VideoResult(keypoints, world, read, dropped, files, seconds)
