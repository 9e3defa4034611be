"""The no-learning guess of where a person stands, the baseline every absolute figure is set beside: the
mid-ankle pixel's ray meeting the plane ``ANKLE_HEIGHT_M`` above the floor."""

from __future__ import annotations

import numpy as np

from ray3d.geometry import Camera
from ray3d.skeleton import H36M17, convert_keypoints

ANKLE_HEIGHT_M = 0.08
_ANKLES = [H36M17.index("l_ankle"), H36M17.index("r_ankle")]


def floor_guess(pixels: np.ndarray, camera: Camera, layout: str = "h36m17") -> np.ndarray:
    """(T, J, 2) detections of ``layout`` (NaN where unseen) -> (T, 3) world points where the mid-ankle pixel's
    ray meets the plane ``ANKLE_HEIGHT_M`` up (NaN where an ankle is unseen or the ray never meets it)."""
    h36m, _ = convert_keypoints(np.asarray(pixels, dtype=np.float64), layout)
    ankles = h36m[:, _ANKLES].mean(axis=1)
    seen = np.isfinite(ankles).all(-1)
    guess = np.full((len(ankles), 3), np.nan)
    guess[seen] = camera.pixels_to_height_plane(ankles[seen], ANKLE_HEIGHT_M)
    return guess
