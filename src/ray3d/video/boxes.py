"""Boxes in the image: x0, y0, x1, y1 in pixels."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment


def outside_picture(pixels: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(..., J, 2) pixels -> (...,) whether any of them lies outside a picture of ``image_size`` (width, height):
    the person cut by its edge (a pose detector puts the joints it cannot see there)."""
    width, height = image_size
    u, v = pixels[..., 0], pixels[..., 1]
    return ((u < 0) | (u >= width) | (v < 0) | (v >= height)).any(axis=-1)


def _intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Areas of the intersections of boxes (..., 4) and (..., 4), broadcast."""
    low, high = np.maximum(a[..., :2], b[..., :2]), np.minimum(a[..., 2:], b[..., 2:])
    return np.prod(np.clip(high - low, 0, None), axis=-1)


def box_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of boxes (N, 4) and (M, 4) -> (N, M)."""
    inter = _intersection(a[:, None], b[None])
    area_a, area_b = (np.prod(x[:, 2:] - x[:, :2], axis=-1) for x in (a, b))
    return inter / np.maximum(area_a[:, None] + area_b[None] - inter, 1e-9)


def whole_person(box: np.ndarray) -> np.ndarray:
    """(..., 4) boxes of a person's keypoints (eyes to ankles) -> (..., 4) the whole person's: a tenth of the height
    over the eyes, a twentieth under the ankles, a tenth of the width either side."""
    box = np.asarray(box, dtype=np.float64)
    tall, wide = box[..., 3] - box[..., 1], box[..., 2] - box[..., 0]
    return np.stack([box[..., 0] - 0.1 * wide, box[..., 1] - 0.1 * tall, box[..., 2] + 0.1 * wide,
                     box[..., 3] + 0.05 * tall], axis=-1)


def box_inside(inner: np.ndarray, outer: np.ndarray) -> float:
    """The share of box ``inner`` (4,) that lies inside box ``outer`` (4,)."""
    return float(_intersection(inner, outer) / max(float(np.prod(inner[2:] - inner[:2])), 1e-9))


def matched_one_to_one(overlap: np.ndarray, at_least: float) -> np.ndarray:
    """(N,) whether each row of ``overlap`` (N, M) is matched: rows and columns paired one to one where they overlap
    most in all (the Hungarian assignment), a row matched where its pair's overlap reaches ``at_least``."""
    rows, columns = linear_sum_assignment(-overlap)
    matched = np.zeros(len(overlap), bool)
    matched[rows[overlap[rows, columns] >= at_least]] = True
    return matched
