"""``lift_video``: frames (OpenCV) -> 2D detections -> world joints -> the world file, the detections (to
re-lift without detecting again), the HTML viewer and an overlay video (the detections and the lifted joints
projected back through the camera, drawn on every frame)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.io.keypoints import Keypoints, write_keypoints_json
from ray3d.io.world import LiftResult, World, write_world
from ray3d.lift import Lifter
from ray3d.skeleton import H36M17, convert_keypoints
from ray3d.video.detectors import PoseDetector
from ray3d.viz.html_viewer import write_viewer

# BGR colours for OpenCV: the person's left blue, right red, centre grey (as the other figures).
_BGR = {"l_": (214, 95, 31), "r_": (47, 47, 214), "": (80, 80, 80)}


@dataclasses.dataclass(frozen=True)
class VideoInfo:
    path: Path
    frames: int
    fps: float
    image_size: tuple[int, int]


@dataclasses.dataclass
class VideoResult:
    """The detections (T, J, 2) and confidences (T, J) in the detector's layout, the lifted world joints and
    the files written."""

    keypoints: np.ndarray
    confidences: np.ndarray
    layout: str
    lifted: LiftResult
    files: dict[str, Path]


def read_video_info(path: str | Path) -> VideoInfo:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such video file")
    capture = cv2.VideoCapture(str(path))
    try:
        if not capture.isOpened():
            raise InputError(f"{path}: OpenCV cannot open it as a video")
        frames = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        fps = float(capture.get(cv2.CAP_PROP_FPS))
        size = (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    finally:
        capture.release()
    if min(size) <= 0:
        raise InputError(f"{path}: the video reports no frame size")
    return VideoInfo(path, frames, fps, size)


def _frames(path: Path) -> Iterator[np.ndarray]:
    """The video's frames as RGB uint8 arrays."""
    capture = cv2.VideoCapture(str(path))
    try:
        while True:
            ok, frame = capture.read()
            if not ok:
                return
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    finally:
        capture.release()


def detect_video(path: str | Path, detector: PoseDetector, progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Run ``detector`` on every frame: (T, J, 2) pixels and (T, J) confidences."""
    info = read_video_info(path)
    pixels, confidences = [], []
    for frame in tqdm(_frames(info.path), total=info.frames or None, desc="detecting", unit="frame",
                      disable=not progress):
        p, c = detector(frame)
        pixels.append(p)
        confidences.append(c)
    if not pixels:
        raise InputError(f"{path}: no frames could be read")
    return np.asarray(pixels, dtype=np.float64), np.asarray(confidences, dtype=np.float64)


def video_keypoints(path: str | Path, detector: PoseDetector, fps: float | None = None,
                    progress: bool = True) -> Keypoints:
    """The detections of every frame of a video as ``Keypoints`` (one track), at the video's frame rate
    unless ``fps`` is given."""
    info = read_video_info(path)
    pixels, confidences = detect_video(info.path, detector, progress)
    return Keypoints(pixels, confidences, np.arange(len(pixels)), np.zeros(len(pixels), dtype=np.int64),
                     detector.layout, fps or info.fps, f"{detector.layout} detections", info.path)


def lift_video(path: str | Path, camera: Camera, out_dir: str | Path, detector: PoseDetector,
               lifter: Lifter | None = None, fps: float | None = None, world_format: str = ".json",
               overlay: bool = True, overwrite: bool = False, progress: bool = True, **lift_options) -> VideoResult:
    """Detect, lift and write ``out_dir``/{world.json|.csv|.npz, keypoints.json, viewer.html, overlay.mp4}.

    ``camera`` must have the video's image size; ``fps`` overrides the frame rate the video reports.
    ``lift_options`` go to ``Lifter.lift`` (smoothing, flip test).
    """
    info = read_video_info(path)
    if tuple(camera.image_size) != info.image_size:
        raise InputError(f"camera {camera.name or ''}: image size {tuple(camera.image_size)} but {info.path} is "
                         f"{info.image_size[0]}x{info.image_size[1]}")
    fps = fps or info.fps
    if not fps or fps <= 0:
        raise InputError(f"{info.path}: the video reports no frame rate; give it", arguments=("fps",))
    out_dir = Path(out_dir)
    targets = {"world": out_dir / f"world{world_format}", "keypoints": out_dir / "keypoints.json",
               "viewer": out_dir / "viewer.html", **({"overlay": out_dir / "overlay.mp4"} if overlay else {})}
    existing = [str(p) for p in targets.values() if p.exists()]
    if existing and not overwrite:
        raise InputError(f"{', '.join(existing)}: already exist(s); refusing to overwrite", arguments=("overwrite",))
    keypoints, confidences = detect_video(info.path, detector, progress)
    if not (confidences > 0).any():
        raise InputError(f"{info.path}: the detector found nobody in any of its {len(keypoints)} frames")
    lifter = lifter or Lifter.load()
    lifted = lifter.lift(keypoints, camera, confidences, fps, detector.layout, **lift_options)
    write_world(targets["world"], World({"0": lifted}, camera, lifter.name), overwrite=overwrite)
    write_keypoints_json(targets["keypoints"], keypoints, confidences, detector.layout, fps, overwrite)
    write_viewer(targets["viewer"], {"ray3d": lifted.joints}, fps, camera, title=f"ray3d: {info.path.name}",
                 overwrite=overwrite)
    if overlay:
        pixels, _ = convert_keypoints(keypoints, detector.layout, confidences)
        write_overlay(info.path, targets["overlay"], pixels, camera.project(lifted.joints), fps, overwrite, progress)
    return VideoResult(keypoints, confidences, detector.layout, lifted, targets)


def write_overlay(video: Path, target: Path, detected: np.ndarray, lifted: np.ndarray, fps: float,
                  overwrite: bool = False, progress: bool = True) -> Path:
    """Draw the detections (thin, (T, 17, 2)) and the lifted joints projected back (thick, (T, 17, 2)) on
    every frame of ``video`` and write an MP4."""
    info = read_video_info(video)
    with atomic_path(target, overwrite) as temporary:
        writer = cv2.VideoWriter(str(temporary), cv2.VideoWriter_fourcc(*"mp4v"), fps, info.image_size)
        if not writer.isOpened():
            raise InputError(f"{target}: OpenCV cannot write MP4 video here")
        try:
            for t, frame in enumerate(tqdm(_frames(video), total=len(lifted), desc="overlay", unit="frame",
                                           disable=not progress)):
                if t >= len(lifted):
                    break
                canvas = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
                for points, width in ((detected[t], 1), (lifted[t], 3)):
                    _draw_skeleton(canvas, points, width)
                writer.write(canvas)
        finally:
            writer.release()
    return target


def _draw_skeleton(canvas: np.ndarray, points: np.ndarray, width: int) -> None:
    for child, parent in enumerate(H36M17.parents):
        if parent < 0 or not np.isfinite(points[[child, parent]]).all():
            continue
        colour = _BGR[H36M17.joint_names[child][:2] if H36M17.joint_names[child][:2] in ("l_", "r_") else ""]
        start, end = (tuple(int(round(v)) for v in points[i]) for i in (child, parent))
        cv2.line(canvas, start, end, colour, width, cv2.LINE_AA)

