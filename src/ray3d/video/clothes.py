"""The colours of a person's clothes, which tell two people apart where their places do not: the boxes of the
jacket and the trousers from the joints, a hue-saturation histogram of each, and how far apart two such are."""

from __future__ import annotations

import cv2
import numpy as np

from ray3d.skeleton import H36M17
from ray3d.video.detectors import Detection

_TORSO = [H36M17.joint_names.index(j) for j in ("l_shoulder", "r_shoulder", "l_hip", "r_hip")]
_LEGS = [H36M17.joint_names.index(j) for j in ("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle")]
COLOUR_GATE = 0.6  # Bhattacharyya distance of clothes colours beyond which two detections are different people


def clothes_boxes(detection: Detection, pixels: np.ndarray, seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(4,) the box of the shoulders and hips and (4,) that of the hips, knees and ankles (the jacket and the
    trousers, not the neighbour's arm), from the H36M-17 ``pixels`` (17, 2) ``seen`` (17,); where those joints are
    not seen, the parts of the person's box they usually take."""
    x0, y0, x1, y1 = detection.box
    boxes = []
    for joints, top, bottom in ((_TORSO, 0.2, 0.55), (_LEGS, 0.5, 1.0)):
        found = pixels[joints][seen[joints]]
        if len(found) >= 3:
            boxes.append(np.concatenate([found.min(axis=0), found.max(axis=0)]))
        else:
            boxes.append(np.array([x0 + 0.2 * (x1 - x0), y0 + top * (y1 - y0), x1 - 0.2 * (x1 - x0),
                                   y0 + bottom * (y1 - y0)]))
    return boxes[0], boxes[1]


def clothes_colour(frame: np.ndarray, torso: np.ndarray, legs: np.ndarray) -> np.ndarray:
    """The clothes' colours: a hue-saturation histogram (8 x 4) of the frame inside the torso's box and one inside
    the legs' box, each normalised, side by side and halved (one distribution: a dark jacket over jeans is told from
    the same jacket over black trousers)."""
    return np.concatenate([_hue_saturation(frame, torso), _hue_saturation(frame, legs)]) / 2


def _hue_saturation(frame: np.ndarray, box: np.ndarray) -> np.ndarray:
    """A normalised hue-saturation histogram (8 x 4) of the frame inside a box."""
    height, width = frame.shape[:2]
    x0, y0, x1, y1 = box
    u0, u1 = int(np.clip(x0, 0, width - 1)), int(np.clip(x1, 1, width))
    v0, v1 = int(np.clip(y0, 0, height - 1)), int(np.clip(y1, 1, height))
    patch = frame[v0:max(v1, v0 + 1), u0:max(u1, u0 + 1)]
    hsv = cv2.cvtColor(np.ascontiguousarray(patch), cv2.COLOR_RGB2HSV)
    histogram = cv2.calcHist([hsv], [0, 1], None, [8, 4], [0, 180, 0, 256]).ravel()
    return histogram / max(float(histogram.sum()), 1e-9)


def colour_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Bhattacharyya distance of two normalised histograms: 0 the same, 1 nothing in common."""
    return float(np.sqrt(max(0.0, 1.0 - np.sum(np.sqrt(a * b)))))
