"""Reading a video with OpenCV: its size, rate and length, its frames one at a time (never all in memory), and
a few frames spread over it."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera

BACKGROUND_SAMPLES = 25  # frames spread over the video from which a fixed camera's empty scene is learnt


@dataclasses.dataclass(frozen=True)
class VideoInfo:
    path: Path
    frames: int
    fps: float
    image_size: tuple[int, int]


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
    return VideoInfo(path, frames, fps if np.isfinite(fps) else 0.0, size)


CODED_BLOCK_PX = 16  # video codecs code frames in blocks of 16 px and crop: 1080 rows are coded as 1088


def camera_for_video(camera: Camera, info: VideoInfo) -> Camera:
    """``camera`` with the video's image size: the same camera when the sizes agree, or when the camera was
    calibrated on the coded frame (up to a block of 16 px more to the right and below, a multiple of 16: the
    pixel grid is the same, the decoder crops the padding); any other difference is refused."""
    if tuple(camera.image_size) == info.image_size:
        return camera
    padding = np.subtract(camera.image_size, info.image_size)
    coded = not (np.asarray(camera.image_size) % CODED_BLOCK_PX).any()
    if coded and ((padding >= 0) & (padding < CODED_BLOCK_PX)).all():
        return dataclasses.replace(camera, image_size=info.image_size)
    raise InputError(f"camera {camera.name or ''}: image size {tuple(camera.image_size)} but {info.path} is "
                     f"{info.image_size[0]}x{info.image_size[1]}", arguments=("camera",))


def read_frames(path: Path, start: int = 0, count: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """(frame index, RGB uint8 frame) for ``count`` frames from ``start`` (all to the end by default)."""
    capture = cv2.VideoCapture(str(path))
    try:
        if start:
            capture.set(cv2.CAP_PROP_POS_FRAMES, start)
        index = start
        while count is None or index < start + count:
            ok, frame = capture.read()
            if not ok:
                return
            yield index, cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
            index += 1
    finally:
        capture.release()


def spread_frames(info: VideoInfo, start: int, count: int, samples: int = BACKGROUND_SAMPLES) -> list[np.ndarray]:
    """Up to ``samples`` frames spread evenly over frames start .. start + count."""
    wanted = set(np.linspace(start, start + count - 1, min(samples, count)).round().astype(int).tolist())
    capture = cv2.VideoCapture(str(info.path))
    frames = []
    try:
        for index in sorted(wanted):
            capture.set(cv2.CAP_PROP_POS_FRAMES, index)
            ok, frame = capture.read()
            if ok:
                frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    finally:
        capture.release()
    return frames


