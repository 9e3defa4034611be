"""The overlay video: on every frame, each person's detections (thin, white) and lifted joints projected back
through the camera (thick, in the person's colour, labelled with their track id). Frames a track did not
detect but filled in are drawn thin and grey; nothing is drawn where nobody was."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ray3d.console import progress_bar
from ray3d.errors import InputError
from ray3d.io.atomic import atomic_path
from ray3d.io.keypoints import Keypoints
from ray3d.io.world import World
from ray3d.skeleton import H36M17
from ray3d.video.frames import VideoInfo, read_frames
from ray3d.viz.animation import PALETTE

# The viewer's colours, in OpenCV's BGR: a person has the same colour in the overlay and the viewer.
TRACK_COLOURS = tuple(tuple(int(h[i:i + 2], 16) for i in (5, 3, 1)) for h in PALETTE)
_FILLED, _DETECTED = (150, 150, 150), (255, 255, 255)
_CHILDREN = np.flatnonzero(np.asarray(H36M17.parents) >= 0)
_PARENTS = np.asarray(H36M17.parents)[_CHILDREN]


def write_overlay(video: VideoInfo, target: Path, keypoints: Keypoints, world: World, start: int, frames: int,
                  overwrite: bool = False, progress: bool = True) -> Path:
    """Draw every track of ``world`` (and its ``keypoints``) on ``frames`` frames of ``video`` from ``start``;
    MP4 at the keypoints' frame rate."""
    projected = {name: (result.frames, world.camera.project(result.joints), result.interpolated.all(axis=1),
                        TRACK_COLOURS[i % len(TRACK_COLOURS)], keypoints.h36m_pixels(name, result.frames))
                 for i, (name, result) in enumerate(world.tracks.items())}
    with atomic_path(target, overwrite) as temporary:
        writer = cv2.VideoWriter(str(temporary), cv2.VideoWriter_fourcc(*"mp4v"), keypoints.fps, video.image_size)
        if not writer.isOpened():
            raise InputError(f"{target}: OpenCV cannot write MP4 video here")
        try:
            for index, frame in progress_bar(read_frames(video.path, start, frames), shown=progress, total=frames,
                                             desc="overlay", unit="frame"):
                canvas = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
                for name, (spanned, pixels, filled, own, detected) in projected.items():
                    row = index - int(spanned[0])
                    if not 0 <= row < len(spanned):
                        continue
                    if np.isfinite(detected[row]).any():
                        _draw_skeleton(canvas, detected[row], _DETECTED, 1)
                    colour, width = (_FILLED, 1) if filled[row] else (own, 2)
                    _draw_skeleton(canvas, pixels[row], colour, width)
                    _label(canvas, pixels[row], name, colour)
                writer.write(canvas)
        finally:
            writer.release()
    return target


def _draw_skeleton(canvas: np.ndarray, points: np.ndarray, colour, width: int) -> None:
    """The bones of ``points`` (17, 2: H36M17 pixels) whose two ends are known, in one drawing call."""
    bones = np.stack([points[_CHILDREN], points[_PARENTS]], axis=1)
    bones = bones[np.isfinite(bones).all(axis=(1, 2))]
    cv2.polylines(canvas, np.round(bones).astype(np.int32), False, colour, width, cv2.LINE_AA)


def _label(canvas: np.ndarray, points: np.ndarray, text: str, colour) -> None:
    seen = points[np.isfinite(points).all(-1)]
    if not len(seen):
        return
    u, v = int(seen[:, 0].mean()) - 4, int(seen[:, 1].min()) - 6
    cv2.putText(canvas, text, (u, v), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(canvas, text, (u, v), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv2.LINE_AA)
