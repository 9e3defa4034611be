"""RFRH ("root at a fixed real height"): the paper's no-learning absolute-position baseline.

The root joint (pelvis) is placed where its pixel's ray through the camera reaches a fixed height above the
floor. Exact when the true pelvis is at that height; its error grows as the person crouches, jumps or the
camera looks along the floor (the ray meets the height plane at a grazing angle).
"""

from __future__ import annotations

from ray3d.errors import InputError
from ray3d.geometry.arrays import Array, check_points, like, namespace, to_numpy
from ray3d.geometry.camera import Camera
from ray3d.geometry.transforms import camera_to_world

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
    xp = namespace(root_pixels)
    uv = check_points(root_pixels, 2, "root_pixels")
    rays_camera = camera.pixels_to_rays(uv, frame="camera")
    center = like(camera.center, uv)
    directions = camera_to_world(rays_camera, like(camera.R, uv), like(camera.t, uv)) - center
    # Solve C_z + s * d_z = root_height for the ray parameter s; only s > 0 lies in front of the camera.
    dz = directions[..., 2]
    safe_dz = xp.where(dz != 0, dz, xp.ones_like(dz))
    s = (root_height - center[2]) / safe_dz
    reachable = (dz != 0) & (s > 0) & xp.isfinite(s)
    if not bool(to_numpy(reachable).all()) and unreachable == "raise":
        bad = to_numpy(~reachable).reshape(-1).nonzero()[0]
        raise InputError(
            f"rfrh_root: the rays of {len(bad)} root pixel(s) (first at flat index {bad[0]}) never reach the height "
            f"{root_height} m above the floor (camera {camera.name or 'unnamed'} is {camera.camera_height:.3f} m "
            "high); pass unreachable='nan' to get NaN there")
    s = xp.where(reachable, s, xp.full_like(s, float("nan")))
    return center + s[..., None] * directions
