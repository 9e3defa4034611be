"""Pure, vectorised transforms between the world, camera and normalized (NCS) frames, and pixels <-> rays.

Frames (brief section 2):
- world: metres, right-handed, z up, floor z = 0;
- camera: OpenCV, x right, y down, z forward; ``X_c = R X_w + t``;
- normalized (NCS): the camera frame rotated about its x axis by the pitch and moved so the origin lies on
  the floor below the camera: ``X_n = R_c2n(pitch) X_c + (0, -height, 0)``. y_n points down (for zero
  roll), z_n is the horizontal heading, and the camera centre sits at (0, -height, 0).

Every function takes numpy arrays or torch tensors. Camera parameters broadcast against the points' leading
axes, so one call can transform a batch of samples seen by a batch of different cameras.
"""

from __future__ import annotations

import numpy as np

from ray3d.geometry.arrays import Array, namespace, stack_last
from ray3d.geometry.distortion import distort, undistort


def _rotate(R: Array, points: Array) -> Array:
    """(..., 3, 3) @ (..., 3) -> (..., 3)."""
    return (R @ points[..., None])[..., 0]


def world_to_camera(points_world: Array, R: Array, t: Array) -> Array:
    """(..., 3) world points to the camera frame, with ``R`` (..., 3, 3) and ``t`` (..., 3) world->camera."""
    return _rotate(R, points_world) + t


def camera_to_world(points_camera: Array, R: Array, t: Array) -> Array:
    """Inverse of :func:`world_to_camera`: ``X_w = R^T (X_c - t)``."""
    return _rotate(R.swapaxes(-1, -2), points_camera - t)


def _rotate_in_plane(points: Array, angle: Array, first: int, second: int) -> Array:
    """Rotate (..., 3) points in the plane of axes ``first`` -> ``second`` by ``angle`` (broadcasting to (...)):
    ``first' = c first - s second``, ``second' = s first + c second``."""
    xp = namespace(points)
    c, s = xp.cos(angle), xp.sin(angle)
    axes = [points[..., 0], points[..., 1], points[..., 2]]
    a, b = axes[first], axes[second]
    axes[first], axes[second] = c * a - s * b, s * a + c * b
    return stack_last(axes)


def _rotate_about_x(points: Array, pitch: Array) -> Array:
    """Rotate (..., 3) points by ``R_c2n(pitch)`` = [[1,0,0],[0,c,s],[0,-s,c]]; ``pitch`` broadcasts to (...)."""
    return _rotate_in_plane(points, pitch, 2, 1)


def _rotate_about_z(points: Array, angle: Array) -> Array:
    """Rotate (..., 3) points about the z (optical) axis by ``angle``."""
    return _rotate_in_plane(points, angle, 0, 1)


def rays_camera_to_normalized(rays_camera: Array, pitch: Array, roll: Array | None = None) -> Array:
    """Rotate (..., 3) camera-frame directions into the NCS (no translation).

    With ``roll`` (radians, see :func:`camera_roll`) the NCS is gravity-aligned: the roll is undone first, so
    world up maps to (0, -1, 0) even for a rolled camera. Without it, the paper's NCS (pitch only).
    """
    if roll is not None:
        rays_camera = _rotate_about_z(rays_camera, -roll)
    return _rotate_about_x(rays_camera, pitch)


def rays_normalized_to_camera(rays_normalized: Array, pitch: Array, roll: Array | None = None) -> Array:
    """Inverse of :func:`rays_camera_to_normalized`."""
    rays = _rotate_about_x(rays_normalized, -pitch)
    return rays if roll is None else _rotate_about_z(rays, roll)


def camera_to_normalized(points_camera: Array, height: Array, pitch: Array, roll: Array | None = None) -> Array:
    """(..., 3) camera-frame points to NCS; ``height`` (metres), ``pitch`` and optional ``roll`` (radians,
    gravity-aligned NCS) broadcast to (...)."""
    rotated = rays_camera_to_normalized(points_camera, pitch, roll)
    return stack_last([rotated[..., 0], rotated[..., 1] - height, rotated[..., 2]])


def normalized_to_camera(points_normalized: Array, height: Array, pitch: Array, roll: Array | None = None) -> Array:
    """Inverse of :func:`camera_to_normalized`."""
    p = points_normalized
    return rays_normalized_to_camera(stack_last([p[..., 0], p[..., 1] + height, p[..., 2]]), pitch, roll)


def pixels_to_camera_rays(pixels: Array, intrinsics: Array, dist: Array | None = None,
                          initial_rays: Array | None = None) -> Array:
    """Back-project pixels to camera-frame rays ``(x, y, 1)`` (intrinsic decoupling).

    Args:
        pixels: (..., 2) pixel coordinates (u, v).
        intrinsics: (..., 4) fx, fy, cx, cy in pixels, broadcastable against the leading axes.
        dist: optional (..., 5) OpenCV coefficients; the pixels are undistorted first.
        initial_rays: optional (..., 3) rays close to the answer, to start the undistortion from.

    Returns:
        (..., 3) rays with unit z: every point on the ray is ``depth * ray``.
    """
    xy = stack_last([
        (pixels[..., 0] - intrinsics[..., 2]) / intrinsics[..., 0],
        (pixels[..., 1] - intrinsics[..., 3]) / intrinsics[..., 1],
    ])
    if dist is not None:
        xy = undistort(xy, dist) if initial_rays is None else undistort(xy, dist, initial_rays[..., :2], iterations=4)
    unit_z = xy[..., 0] * 0 + 1  # NaN where the lens model could not be inverted: the whole ray is undefined
    return stack_last([xy[..., 0], xy[..., 1], unit_z])


def camera_to_pixels(points_camera: Array, intrinsics: Array, dist: Array | None = None) -> Array:
    """Project (..., 3) camera-frame points to (..., 2) pixels, with lens distortion when ``dist`` is given.

    Points at or behind the camera (z <= 0) have no image and come out as NaN.
    """
    xp = namespace(points_camera)
    z = points_camera[..., 2]
    in_front = z > 0
    safe_z = xp.where(in_front, z, xp.ones_like(z))
    xy = points_camera[..., :2] / safe_z[..., None]
    if dist is not None:
        xy = distort(xy, dist)
    u = intrinsics[..., 0] * xy[..., 0] + intrinsics[..., 2]
    v = intrinsics[..., 1] * xy[..., 1] + intrinsics[..., 3]
    nan = xp.full_like(u, float("nan"))
    return stack_last([xp.where(in_front, u, nan), xp.where(in_front, v, nan)])


def camera_center(R: Array, t: Array) -> Array:
    """(..., 3) camera centre in the world, ``C = -R^T t``."""
    return -_rotate(R.swapaxes(-1, -2), t)


def camera_pitch(R: Array) -> Array:
    """(...) pitch in radians from (..., 3, 3) world->camera rotations: the optical axis' angle below horizontal.

    The optical axis in the world is ``R^T (0, 0, 1)`` (the third row of R); pitch = acos(axis_z) - pi/2.
    """
    xp = namespace(R)
    return -xp.arcsin(xp.clip(R[..., 2, 2], -1.0, 1.0))


def camera_roll(R: Array) -> Array:
    """(...) roll in radians: rotation of the image about the optical axis relative to the world's vertical.

    With world up expressed in the camera frame ``u = R (0, 0, 1)``, roll = atan2(u_x, -u_y); zero when the
    camera's x axis is horizontal, positive when world up leans towards +x (image right).
    """
    return namespace(R).arctan2(R[..., 0, 2], -R[..., 1, 2])


def rotation_from_angles(yaw: Array, pitch: Array, roll: Array = 0.0) -> np.ndarray:
    """(..., 3, 3) world->camera rotations of cameras with the given heading, pitch and roll (radians, numpy).

    ``yaw`` is the heading of the optical axis in the floor plane, counter-clockwise from +x; ``pitch`` > 0
    looks down; ``roll`` turns the image about the optical axis with the sign of :func:`camera_roll`.
    Inverse of (:func:`camera_pitch`, :func:`camera_roll`) for the pitch and roll. Angles broadcast.
    """
    yaw, pitch, roll = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (yaw, pitch, roll)))
    forward = forward_direction(yaw, pitch)
    right_level = np.stack([np.sin(yaw), -np.cos(yaw), np.zeros_like(yaw)], -1)
    down_level = np.cross(forward, right_level)
    c, s = np.cos(roll)[..., None], np.sin(roll)[..., None]
    return np.stack([c * right_level - s * down_level, s * right_level + c * down_level, forward], -2)


def forward_direction(yaw: Array, pitch: Array) -> np.ndarray:
    """(..., 3) unit world direction of the optical axis of cameras with heading ``yaw`` and ``pitch`` (radians,
    as :func:`rotation_from_angles`)."""
    yaw, pitch = np.broadcast_arrays(np.asarray(yaw, dtype=np.float64), np.asarray(pitch, dtype=np.float64))
    return np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), -np.sin(pitch)], -1)


def centre_looking_at(target: Array, yaw: Array, pitch: Array, distance: Array) -> np.ndarray:
    """(..., 3) world centres of cameras that look at (..., 3) ``target`` along (yaw, pitch) from ``distance``
    metres away: the one way every camera set, sampler and benchmark places its cameras."""
    return np.asarray(target, dtype=np.float64) - np.asarray(distance, dtype=np.float64)[..., None] * \
        forward_direction(yaw, pitch)


def y_up_to_z_up(points: Array) -> Array:
    """(..., 3) points of a y-up frame (x, y, z) -> the z-up world (x, -z, y): a rotation about x, no mirroring."""
    return stack_last([points[..., 0], -points[..., 2], points[..., 1]])
