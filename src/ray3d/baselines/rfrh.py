"""RFRH ("root at a fixed real height"): the paper's no-learning absolute-position baseline.

The root joint (pelvis) is placed where its pixel's ray through the camera reaches a fixed height above the
floor. Exact when the true pelvis is at that height; its error grows as the person crouches, jumps or the
camera looks along the floor (the ray meets the height plane at a grazing angle).
"""

from __future__ import annotations

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.arrays import Array, check_points, to_numpy
from ray3d.geometry.camera import Camera

DEFAULT_ROOT_HEIGHT_M = 0.9395


def rfrh_root(root_pixels: Array, camera: Camera, root_height: float = DEFAULT_ROOT_HEIGHT_M,
              unreachable: str = "raise") -> Array:
    """World root positions from the root joint's pixels.

    Args:
        root_pixels: (..., 2) pixel coordinates of the root joint (distorted, as observed).
        camera: the calibrated camera that saw them.
        root_height: assumed height of the root above the floor, metres.
        unreachable: ``"raise"`` (default) or ``"nan"``: what to do where the ray never reaches that height
            (it points away from the plane or runs parallel to it).

    Returns:
        (..., 3) world positions with z == ``root_height``.
    """
    if unreachable not in ("raise", "nan"):
        raise InputError(f"rfrh_root: unreachable must be 'raise' or 'nan', got {unreachable!r}")
    points = camera.pixels_to_height_plane(check_points(root_pixels, 2, "root_pixels"), root_height)
    reachable = ~np.isnan(to_numpy(points[..., 0]))
    if not reachable.all() and unreachable == "raise":
        bad = (~reachable).reshape(-1).nonzero()[0]
        raise InputError(
            f"rfrh_root: the rays of {len(bad)} root pixel(s) (first at flat index {bad[0]}) never reach the height "
            f"{root_height} m above the floor (camera {camera.name or 'unnamed'} is {camera.camera_height:.3f} m "
            "high); pass unreachable='nan' to get NaN there")
    return points
