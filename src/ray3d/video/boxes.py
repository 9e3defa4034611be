"""Boxes in the image: x0, y0, x1, y1 in pixels."""

from __future__ import annotations

import numpy as np


def outside_picture(pixels: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(..., J, 2) pixels -> (...,) whether any of them lies outside a picture of ``image_size`` (width, height):
    the person cut by its edge (a pose detector puts the joints it cannot see there)."""
    width, height = image_size
    u, v = pixels[..., 0], pixels[..., 1]
    return ((u < 0) | (u >= width) | (v < 0) | (v >= height)).any(axis=-1)


def box_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of boxes (N, 4) and (M, 4) -> (N, M)."""
    low = np.maximum(a[:, None, :2], b[None, :, :2])
    high = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(high - low, 0, None), axis=-1)
    area_a, area_b = (np.prod(x[:, 2:] - x[:, :2], axis=-1) for x in (a, b))
    return inter / np.maximum(area_a[:, None] + area_b[None] - inter, 1e-9)
