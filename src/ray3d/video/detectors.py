"""2D pose detectors: anything with a ``layout`` (a ``ray3d.skeleton`` layout name) that maps an RGB frame to
one person's pixels and confidences. MediaPipe Pose 0.10.21 is the one found to run fully offline from a
registry package (``pip install 'ray3d[video]'``): its wheel bundles the ``model_complexity=1`` landmark model."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ray3d.errors import InputError
from ray3d.skeleton import BLAZEPOSE33


class PoseDetector(Protocol):
    """One person per frame: ``detector(frame)`` with an (H, W, 3) uint8 RGB frame returns pixels (J, 2) and
    confidences (J,) in ``layout``; NaN pixels and zero confidences where nobody (or no joint) was found."""

    layout: str

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class MediaPipeDetector:
    """MediaPipe Pose (BlazePose, 33 landmarks), tracking across frames (video mode).

    Its landmarks are surface points (e.g. the hip landmarks lie outside the hip joint centres the mocap has):
    ``ray3d.skeleton`` maps them to H36M-17 joints, and the residual offset is a systematic 2D error the
    shipped models were not trained for (see the README's limitations).
    """

    layout = BLAZEPOSE33.name

    def __init__(self, min_detection_confidence: float = 0.5, min_tracking_confidence: float = 0.5):
        try:
            from mediapipe.python.solutions import pose
        except ImportError:
            raise InputError("the MediaPipe detector needs the video extra: pip install 'ray3d[video]'") from None
        # model_complexity=1 is the landmark model the wheel bundles; the others would be downloaded.
        self._pose = pose.Pose(static_image_mode=False, model_complexity=1, smooth_landmarks=True,
                               min_detection_confidence=min_detection_confidence,
                               min_tracking_confidence=min_tracking_confidence)

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        height, width = frame.shape[:2]
        result = self._pose.process(np.ascontiguousarray(frame))
        if result.pose_landmarks is None:
            return np.full((BLAZEPOSE33.num_joints, 2), np.nan), np.zeros(BLAZEPOSE33.num_joints)
        landmarks = result.pose_landmarks.landmark
        pixels = np.array([[m.x * width, m.y * height] for m in landmarks])
        return pixels, np.array([m.visibility for m in landmarks])

    def close(self) -> None:
        self._pose.close()


DETECTORS = {"mediapipe": MediaPipeDetector}


def make_detector(name: str) -> PoseDetector:
    if name not in DETECTORS:
        raise InputError(f"unknown detector {name!r}; one of {', '.join(DETECTORS)}")
    return DETECTORS[name]()
