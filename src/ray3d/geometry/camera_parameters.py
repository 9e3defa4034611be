"""``CameraParameters``: what a calibrated camera is (intrinsics, distortion, pose, image size), each field checked
once when it is built, and the forms users have those numbers in, read and written. What the numbers do to points
and pixels is :class:`ray3d.geometry.camera.Camera`'s (a ``Camera`` is its parameters)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
from scipy.spatial.transform import Rotation

from ray3d.errors import InputError, missing_fields
from ray3d.geometry import transforms as tf
from ray3d.geometry.arrays import numeric_array
from ray3d.geometry.intrinsics import parse_image_size, pinhole_intrinsics

# Real calibration files write rotations with 7 significant digits (|R R^T - I| ~ 1e-6): within this, R is taken
# as the nearest rotation; beyond it, it is refused.
ORTHONORMAL_TOLERANCE = 1e-4


DICT_FIELDS = ("fx", "fy", "cx", "cy", "dist", "R", "t", "width", "height")


def _frozen(value: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    array = numeric_array(value, f"camera field {name}").copy()
    if array.shape != shape:
        raise InputError(f"camera field {name}: expected shape {shape}, got {array.shape}")
    if not np.isfinite(array).all():
        raise InputError(f"camera field {name}: contains NaN or infinite values")
    array.setflags(write=False)
    return array


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """(3, 3) a matrix within ``ORTHONORMAL_TOLERANCE`` of a rotation -> that rotation (the orthonormal factor
    of its polar decomposition, by SVD); anything further from one is refused, its deviation named."""
    error = np.abs(R @ R.T - np.eye(3)).max()
    if error > ORTHONORMAL_TOLERANCE or np.linalg.det(R) < 0:
        raise InputError(f"camera field R: not a rotation (|R R^T - I| = {error:.2e}, det = {np.linalg.det(R):.4f}; "
                         f"at most {ORTHONORMAL_TOLERANCE:g} is taken as rounding)")
    if error < 1e-12:  # a rotation to float rounding: kept bit for bit
        return R
    u, _, vt = np.linalg.svd(R)
    return u @ vt


def checked_intrinsic_matrix(K: Any) -> np.ndarray:
    """(3, 3) ``K`` frozen; refused unless it is [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0."""
    K = _frozen(K, (3, 3), "K")
    fx, fy = K[0, 0], K[1, 1]
    if fx <= 0 or fy <= 0:
        raise InputError(f"camera field K: singular or flipped intrinsics (fx={fx}, fy={fy}); both must be > 0")
    if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
        raise InputError("camera field K: must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), "
                         f"got {K.tolist()}")
    return K


def checked_rotation(R: Any) -> np.ndarray:
    """(3, 3) ``R`` frozen as the nearest rotation (:func:`nearest_rotation`)."""
    return _frozen(nearest_rotation(_frozen(R, (3, 3), "R")), (3, 3), "R")


def checked_distortion(dist: Any) -> np.ndarray:
    """(5,) OpenCV k1, k2, p1, p2, k3 frozen; 4 values (no k3) are taken with k3 = 0."""
    n_dist = np.size(dist)
    dist = _frozen(dist, (n_dist,) if n_dist in (4, 5) else (5,), "dist")
    if n_dist == 4:
        dist = _frozen(np.append(dist, 0.0), (5,), "dist")
    return dist


def check_centre_above_floor(R: np.ndarray, t: np.ndarray, name: str) -> None:
    """Refuse a camera whose centre is at or below z = 0: the world must be z up with the floor at z = 0."""
    center_z = tf.camera_center(R, t)[2]
    if center_z <= 0:
        raise InputError(
            f"camera {name or '(unnamed)'}: centre is at z = {center_z:.3f} m, at or below the ground "
            "plane z = 0; the world frame must be z up with the floor at z = 0")


def check_placement(height_m: float, pitch_deg: float, roll_deg: float) -> None:
    """Refuse, naming the argument, a height (metres) or pitch or roll (degrees) no camera placed over a floor
    has."""
    for argument, value, low, high in (("height_m", height_m, 0.0, 1000.0), ("pitch_deg", pitch_deg, -90.0, 90.0),
                                       ("roll_deg", roll_deg, -90.0, 90.0)):
        if not np.isfinite(value) or not low < value < high:
            raise InputError(f"{argument}: expected a value between {low:g} and {high:g}, got {value}",
                             arguments=(argument,))


@dataclasses.dataclass(frozen=True, eq=False)
class CameraParameters:
    """A calibrated camera's numbers, checked: ``X_c = R X_w + t`` (metres), pixels ``K distort(X_c / z_c)``.

    Attributes:
        K: (3, 3) intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels (no skew).
        dist: (5,) OpenCV distortion k1, k2, p1, p2, k3 (4 values are accepted and k3 taken as 0).
        R: (3, 3) world->camera rotation (orthonormal, det +1).
        t: (3,) world->camera translation in metres.
        image_size: (width, height) in pixels.
        name: a stable identifier, e.g. ``h36m:S1:54138969``.

    The world is z up with the floor at z = 0, so the camera centre must be above the floor. Each constructor
    builds the class it is called on: ``Camera.from_dict`` gives a ``Camera``.
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]
    name: str = ""

    def __post_init__(self) -> None:
        # Checked once, here, and read-only after: every method may trust its camera's fields.
        checked = {"K": checked_intrinsic_matrix(self.K), "dist": checked_distortion(self.dist),
                   "R": checked_rotation(self.R), "t": _frozen(self.t, (3,), "t"),
                   "image_size": parse_image_size(self.image_size, "camera field image_size")}
        for field, value in checked.items():
            object.__setattr__(self, field, value)
        check_centre_above_floor(self.R, self.t, self.name)

    @classmethod
    def from_intrinsics(cls, fx: float, fy: float, cx: float, cy: float, dist: Sequence[float] | None,
                        R: Any, t: Any, image_size: tuple[int, int], name: str = "") -> Self:
        """Build from scalar intrinsics; ``dist=None`` means no distortion."""
        fx, fy, cx, cy = (_frozen(value, (), name) for value, name in ((fx, "fx"), (fy, "fy"), (cx, "cx"), (cy, "cy")))
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)
        return cls(K, np.zeros(5) if dist is None else dist, R, t, image_size, name)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], name: str = "") -> Self:
        """Build from the documented JSON form.

        Keys: ``fx, fy, cx, cy`` (pixels), ``dist`` (k1, k2, p1, p2, k3), ``R`` (3x3 world->camera),
        ``t`` (3, metres), ``width, height`` (pixels); optional ``name``.
        """
        missing = missing_fields(d, DICT_FIELDS, "camera")
        if missing:
            label = d.get("name") or name
            raise InputError(f"camera{' ' + label if label else ''}: missing field(s) {', '.join(missing)}")
        return cls.from_intrinsics(d["fx"], d["fy"], d["cx"], d["cy"], d["dist"], d["R"], d["t"],
                                   (d["width"], d["height"]), str(d.get("name", name)))

    def to_dict(self) -> dict[str, Any]:
        """The JSON form read by :meth:`from_dict`."""
        return {
            "name": self.name,
            "fx": float(self.K[0, 0]), "fy": float(self.K[1, 1]), "cx": float(self.K[0, 2]), "cy": float(self.K[1, 2]),
            "dist": self.dist.tolist(), "R": self.R.tolist(), "t": self.t.tolist(),
            "width": self.image_size[0], "height": self.image_size[1],
        }

    @classmethod
    def from_center_quaternion(cls, quaternion_wxyz: Sequence[float], center: Sequence[float], fx: float, fy: float,
                               cx: float, cy: float, dist: Sequence[float] | None, image_size: tuple[int, int],
                               name: str = "") -> Self:
        """Build from the camera->world orientation quaternion (w, x, y, z) and the camera centre in metres.

        This is the convention of VideoPose3D-style camera files: ``X_w = q X_c q* + C``, hence
        ``R = rot(q)^T`` and ``t = -R C``. (Those files store the centre in millimetres: divide by 1000 first.)
        """
        quaternion = _frozen(quaternion_wxyz, (4,), "quaternion")
        if abs(np.linalg.norm(quaternion) - 1) > 1e-3:
            raise InputError(f"camera field quaternion: not a unit quaternion (norm {np.linalg.norm(quaternion):.4f})")
        R = Rotation.from_quat(quaternion, scalar_first=True).as_matrix().T
        return cls.from_intrinsics(fx, fy, cx, cy, dist, R, -R @ _frozen(center, (3,), "center"), image_size, name)

    @classmethod
    def from_pose(cls, center: Sequence[float], yaw: float, pitch: float, roll: float, fx: float, fy: float,
                  cx: float, cy: float, image_size: tuple[int, int], dist: Sequence[float] | None = None,
                  name: str = "") -> Self:
        """Build from the camera centre (world, metres) and yaw, pitch, roll (radians, see
        :func:`ray3d.geometry.rotation_from_angles`)."""
        R = tf.rotation_from_angles(yaw, pitch, roll)
        return cls.from_intrinsics(fx, fy, cx, cy, dist, R, -R @ _frozen(center, (3,), "center"), image_size, name)

    @classmethod
    def from_height_pitch(cls, height_m: float, pitch_deg: float, image_size: tuple[int, int], roll_deg: float = 0.0,
                          focal_px: float | None = None, hfov_deg: float | None = None,
                          dist: Sequence[float] | None = None, name: str = "") -> Self:
        """A camera placed by what a user can measure: its height above the floor, how far it looks down and
        its field of view (or focal length in pixels). The world frame is the floor below the camera: the
        centre is (0, 0, height) and the camera looks along +x; the principal point is the image centre."""
        check_placement(height_m, pitch_deg, roll_deg)
        fx, fy, cx, cy = pinhole_intrinsics(image_size, focal_px, hfov_deg)
        return cls.from_pose([0.0, 0.0, height_m], 0.0, np.radians(pitch_deg), np.radians(roll_deg), fx, fy, cx, cy,
                             image_size, dist, name or f"height{height_m:g}m-pitch{pitch_deg:g}deg")

    def with_origin_at_height(self, height_m: float) -> Self:
        """This camera in the world frame whose z = 0 lies ``height_m`` above this one's (x and y unchanged, every
        z smaller by ``height_m``): ``t + height_m R e_z``. A calibration made on a board on a table is the floor's
        camera with its origin raised; ``with_origin_at_height(floor_z)`` puts z = 0 back on a floor at ``floor_z``."""
        return dataclasses.replace(self, t=self.t + float(height_m) * self.R[:, 2])
