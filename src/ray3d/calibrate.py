"""Camera set-up without a lab: the camera's pose from floor points with known positions (OpenCV solvePnP)."""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.json_files import read_json

MIN_FLOOR_POINTS = 4


def read_floor_points(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) floor positions in metres (z = 0) and (N, 2) pixels from a CSV (columns x, y, u, v) or a JSON list
    of {"x", "y", "u", "v"} objects."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        rows = read_json(path)
        if not isinstance(rows, list):
            raise InputError(f"{path}: expected a list of {{\"x\", \"y\", \"u\", \"v\"}} objects")
    else:
        try:
            with path.open(newline="") as handle:
                rows = list(csv.DictReader(handle))
        except (OSError, UnicodeDecodeError) as err:
            raise InputError(f"{path}: cannot read ({err})") from None
    try:
        values = np.array([[float(r[k]) for k in ("x", "y", "u", "v")] for r in rows])
    except (KeyError, TypeError):
        raise InputError(f"{path}: every floor point needs x, y (metres) and u, v (pixels)") from None
    except ValueError as err:
        raise InputError(f"{path}: non-numeric floor point value ({err})") from None
    if len(values) < MIN_FLOOR_POINTS:
        raise InputError(f"{path}: {len(values)} floor point(s); at least {MIN_FLOOR_POINTS} are needed")
    return values[:, :2], values[:, 2:]


def from_floor_points(floor_xy: np.ndarray, pixels: np.ndarray, intrinsics: Camera | tuple, image_size=None,
                      dist=None, name: str = "floor-calibrated") -> tuple[Camera, float]:
    """The camera's world pose from floor points: returns (camera, RMS reprojection error in pixels).

    ``intrinsics`` is a Camera (its K, distortion and image size are kept) or (fx, fy, cx, cy) with
    ``image_size``. The world frame is that of the floor points, z up.
    """
    if isinstance(intrinsics, Camera):
        K, dist, image_size = intrinsics.K, intrinsics.dist, intrinsics.image_size
    else:
        fx, fy, cx, cy = intrinsics
        K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=np.float64)
    world = np.column_stack([floor_xy, np.zeros(len(floor_xy))]).astype(np.float64)
    ok, rvec, tvec = cv2.solvePnP(world, pixels.astype(np.float64), K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise InputError("calibrate: OpenCV solvePnP found no pose for these floor points")
    rotation, _ = cv2.Rodrigues(rvec)
    # A planar target has a mirror solution behind the floor; the camera must be above the floor.
    if (-rotation.T @ tvec.ravel())[2] <= 0:
        raise InputError("calibrate: the solution puts the camera below the floor; check the points' order and "
                         "that x, y are a right-handed floor frame (z up)")
    camera = Camera(K, dist, rotation, tvec.ravel(), image_size, name)
    rms = float(np.sqrt(((camera.project(world) - pixels) ** 2).sum(-1).mean()))
    return camera, rms
