"""``Camera``: an immutable calibrated pinhole camera with OpenCV distortion, and its frame conversions."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ray3d.errors import InputError
from ray3d.geometry import transforms as tf
from ray3d.geometry.arrays import Array, check_points, like, namespace, numeric_array
from ray3d.geometry.intrinsics import parse_image_size, pinhole_intrinsics

# Real calibration files write rotations with 7 significant digits (|R R^T - I| ~ 1e-6): within this, R is taken
# as the nearest rotation; beyond it, it is refused.
ORTHONORMAL_TOLERANCE = 1e-4
# A camera whose optical axis rises more than this above the horizontal is doubted: people are filmed from above
# or level with them, and a pitch typed with the wrong sign (positive looks down) looks up.
LOOKS_UP_DEG = 5.0


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


@dataclasses.dataclass(frozen=True, eq=False)
class Camera:
    """A calibrated camera: ``X_c = R X_w + t`` (metres), pixels ``K distort(X_c / z_c)``.

    Attributes:
        K: (3, 3) intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels (no skew).
        dist: (5,) OpenCV distortion k1, k2, p1, p2, k3 (4 values are accepted and k3 taken as 0).
        R: (3, 3) world->camera rotation (orthonormal, det +1).
        t: (3,) world->camera translation in metres.
        image_size: (width, height) in pixels.
        name: a stable identifier, e.g. ``h36m:S1:54138969``.

    The world is z up with the floor at z = 0, so the camera centre must be above the floor.
    Every method accepts numpy arrays or torch tensors of any leading shape and returns the same kind
    (torch keeps autograd and device).
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]
    name: str = ""

    def __post_init__(self) -> None:
        K = _frozen(self.K, (3, 3), "K")
        fx, fy = K[0, 0], K[1, 1]
        if fx <= 0 or fy <= 0:
            raise InputError(f"camera field K: singular or flipped intrinsics (fx={fx}, fy={fy}); both must be > 0")
        if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
            raise InputError("camera field K: must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), "
                             f"got {K.tolist()}")
        n_dist = np.size(self.dist)
        dist = _frozen(self.dist, (n_dist,) if n_dist in (4, 5) else (5,), "dist")
        if n_dist == 4:
            dist = _frozen(np.append(dist, 0.0), (5,), "dist")
        R = _frozen(nearest_rotation(_frozen(self.R, (3, 3), "R")), (3, 3), "R")
        t = _frozen(self.t, (3,), "t")
        width, height = parse_image_size(self.image_size, "camera field image_size")
        for field, value in (("K", K), ("dist", dist), ("R", R), ("t", t), ("image_size", (width, height))):
            object.__setattr__(self, field, value)
        center_z = tf.camera_center(R, t)[2]
        if center_z <= 0:
            raise InputError(
                f"camera {self.name or '(unnamed)'}: centre is at z = {center_z:.3f} m, at or below the ground "
                "plane z = 0; the world frame must be z up with the floor at z = 0")

    # ----------------------------------------------------------------------------------------- construction
    @classmethod
    def from_intrinsics(cls, fx: float, fy: float, cx: float, cy: float, dist: Sequence[float] | None,
                        R: Any, t: Any, image_size: tuple[int, int], name: str = "") -> Camera:
        """Build from scalar intrinsics; ``dist=None`` means no distortion."""
        fx, fy, cx, cy = (_frozen(value, (), name) for value, name in ((fx, "fx"), (fy, "fy"), (cx, "cx"), (cy, "cy")))
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)
        return cls(K, np.zeros(5) if dist is None else dist, R, t, image_size, name)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], name: str = "") -> Camera:
        """Build from the documented JSON form.

        Keys: ``fx, fy, cx, cy`` (pixels), ``dist`` (k1, k2, p1, p2, k3), ``R`` (3x3 world->camera),
        ``t`` (3, metres), ``width, height`` (pixels); optional ``name``.
        """
        if not isinstance(d, Mapping):
            raise InputError(f"camera: expected a JSON object, got {type(d).__name__}")
        missing = [key for key in DICT_FIELDS if key not in d]
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
                               name: str = "") -> Camera:
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
                  name: str = "") -> Camera:
        """Build from the camera centre (world, metres) and yaw, pitch, roll (radians, see
        :func:`ray3d.geometry.rotation_from_angles`)."""
        R = tf.rotation_from_angles(yaw, pitch, roll)
        return cls.from_intrinsics(fx, fy, cx, cy, dist, R, -R @ _frozen(center, (3,), "center"), image_size, name)

    @classmethod
    def from_height_pitch(cls, height_m: float, pitch_deg: float, image_size: tuple[int, int], roll_deg: float = 0.0,
                          focal_px: float | None = None, hfov_deg: float | None = None,
                          dist: Sequence[float] | None = None, name: str = "") -> Camera:
        """A camera placed by what a user can measure: its height above the floor, how far it looks down and
        its field of view (or focal length in pixels). The world frame is the floor below the camera: the
        centre is (0, 0, height) and the camera looks along +x; the principal point is the image centre."""
        for argument, value, low, high in (("height_m", height_m, 0.0, 1000.0), ("pitch_deg", pitch_deg, -90.0, 90.0),
                                           ("roll_deg", roll_deg, -90.0, 90.0)):
            if not np.isfinite(value) or not low < value < high:
                raise InputError(f"{argument}: expected a value between {low:g} and {high:g}, got {value}",
                                 arguments=(argument,))
        fx, fy, cx, cy = pinhole_intrinsics(image_size, focal_px, hfov_deg)
        return cls.from_pose([0.0, 0.0, height_m], 0.0, np.radians(pitch_deg), np.radians(roll_deg), fx, fy, cx, cy,
                             image_size, dist, name or f"height{height_m:g}m-pitch{pitch_deg:g}deg")

    # ---------------------------------------------------------------------------------------------- pose
    @property
    def intrinsics(self) -> np.ndarray:
        """(4,) fx, fy, cx, cy."""
        return np.array([self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]])

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in the world, metres."""
        return tf.camera_center(self.R, self.t)

    @property
    def camera_height(self) -> float:
        """Height of the camera centre above the floor, metres."""
        return float(self.center[2])

    @property
    def pitch(self) -> float:
        """Angle of the optical axis below the horizontal, radians (positive looking down)."""
        return float(tf.camera_pitch(self.R))

    @property
    def roll(self) -> float:
        """Rotation about the optical axis relative to the world vertical, radians (ignored by the method)."""
        return float(tf.camera_roll(self.R))

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    # ------------------------------------------------------------------------------------------ frames
    def world_to_camera(self, points_world: Array) -> Array:
        """(..., 3) world points -> camera frame."""
        p = check_points(points_world, 3, "points_world")
        return tf.world_to_camera(p, like(self.R, p), like(self.t, p))

    def camera_to_world(self, points_camera: Array) -> Array:
        """(..., 3) camera-frame points -> world."""
        p = check_points(points_camera, 3, "points_camera")
        return tf.camera_to_world(p, like(self.R, p), like(self.t, p))

    def _ncs(self, ref: Array, remove_roll: bool) -> tuple[Array, Array, Array | None]:
        """(height, pitch, roll or None): what the NCS depends on, in ``ref``'s library, dtype and device."""
        return like(self.camera_height, ref), like(self.pitch, ref), like(self.roll, ref) if remove_roll else None

    def camera_to_normalized(self, points_camera: Array, remove_roll: bool = False) -> Array:
        """(..., 3) camera-frame points -> NCS (``remove_roll``: the gravity-aligned NCS)."""
        p = check_points(points_camera, 3, "points_camera")
        return tf.camera_to_normalized(p, *self._ncs(p, remove_roll))

    def normalized_to_camera(self, points_normalized: Array, remove_roll: bool = False) -> Array:
        """(..., 3) NCS points -> camera frame."""
        p = check_points(points_normalized, 3, "points_normalized")
        return tf.normalized_to_camera(p, *self._ncs(p, remove_roll))

    def world_to_normalized(self, points_world: Array, remove_roll: bool = False) -> Array:
        """(..., 3) world points -> NCS."""
        return self.camera_to_normalized(self.world_to_camera(points_world), remove_roll)

    def normalized_to_world(self, points_normalized: Array, remove_roll: bool = False) -> Array:
        """(..., 3) NCS points -> world."""
        return self.camera_to_world(self.normalized_to_camera(points_normalized, remove_roll))

    # ----------------------------------------------------------------------------------------- pixels
    def project(self, points_world: Array) -> Array:
        """(..., 3) world points -> (..., 2) pixels, lens distortion included; points behind the camera -> NaN."""
        p = self.world_to_camera(points_world)
        return tf.camera_to_pixels(p, like(self.intrinsics, p), like(self.dist, p) if self.has_distortion else None)

    def pixels_to_camera_rays(self, pixels: Array) -> Array:
        """(..., 2) pixels -> (..., 3) camera-frame rays ``(x, y, 1)`` through them, undistorted; NaN where the
        lens model cannot be inverted."""
        uv = check_points(pixels, 2, "pixels")
        return tf.pixels_to_camera_rays(uv, like(self.intrinsics, uv), like(self.dist, uv) if self.has_distortion
                                        else None)

    def pixels_to_rays(self, pixels: Array, remove_roll: bool = False) -> Array:
        """(..., 2) pixels -> (..., 3) their rays in the NCS (the Ray3D network input; not unit length): the
        camera rays rotated by the pitch (and the roll too with ``remove_roll``: the gravity-aligned NCS). A point
        at camera depth z_c on the ray of pixel p satisfies ``X_n = z_c * ray_n + (0, -h, 0)``."""
        rays = self.pixels_to_camera_rays(pixels)
        return tf.rays_camera_to_normalized(rays, *self._ncs(rays, remove_roll)[1:])

    def pixels_to_world_directions(self, pixels: Array) -> Array:
        """(..., 2) pixels -> (..., 3) world directions of their rays from the camera centre, ``R^T (x, y, 1)``
        (not unit length)."""
        rays = self.pixels_to_camera_rays(pixels)
        return rays @ like(self.R, rays)

    def pixels_to_height_plane(self, pixels: Array, height_m: float = 0.0) -> Array:
        """(..., 2) pixels -> (..., 3) world points where their rays meet the horizontal plane ``z = height_m``
        (the floor by default); NaN where a ray never reaches it in front of the camera."""
        xp = namespace(pixels)
        directions = self.pixels_to_world_directions(pixels)
        centre = like(self.center, directions)
        dz = directions[..., 2]
        # Solve C_z + s d_z = height for the ray parameter s; only s > 0 lies in front of the camera.
        s = (height_m - centre[2]) / xp.where(dz != 0, dz, xp.ones_like(dz))
        s = xp.where((dz != 0) & (s > 0) & xp.isfinite(s), s, xp.full_like(s, float("nan")))
        return centre + s[..., None] * directions

    def doubts(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(what makes this camera unusable, what makes it implausible for people on a floor), each a clause naming
        the camera. Unusable: a lens whose distortion turns back inside the image (its rays cannot be recovered
        there). Implausible: a field of view across the image under 3 or over 170 degrees; a principal point more
        than an image's size outside it; an image whose lowest row looks above the horizon (the floor where
        people stand unseen); else an optical axis rising more than ``LOOKS_UP_DEG`` (a pitch of the wrong sign)."""
        name = f"camera {self.name}" if self.name else "the camera"
        width, height = self.image_size
        fx, fy, cx, cy = self.intrinsics
        corners = (np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float) - [cx, cy]) / [fx, fy]
        reach = float(np.linalg.norm(corners, axis=-1).max())  # the distorted radius the image reaches
        k1, k2, _, _, k3 = (float(v) for v in self.dist)
        radius = np.linspace(0.0, max(4 * reach, 4.0), 4001)
        distorted = radius * (1 + k1 * radius ** 2 + k2 * radius ** 4 + k3 * radius ** 6)
        turning = np.flatnonzero(np.diff(distorted) <= 0)
        if len(turning) and distorted[turning[0]] < reach:
            return (f"{name}'s lens distortion (k1 {k1:g}, k2 {k2:g}, k3 {k3:g}) turns back "
                    f"{distorted[turning[0]]:.2f} focal lengths from the centre, inside the image (which reaches "
                    f"{reach:.2f}): its rays cannot be recovered there",), ()
        doubts = []
        across = 2 * np.degrees(np.arctan(radius[np.searchsorted(distorted, max(cx, width - cx) / fx)]))
        if not 3.0 <= across <= 170.0:
            doubts.append(f"{name} sees {across:.1f} degrees across its image (focal {fx:g} px, k1 {k1:g}): no lens "
                          "people are filmed with")
        if not (-width <= cx <= 2 * width and -height <= cy <= 2 * height):
            doubts.append(f"{name}'s principal point ({cx:g}, {cy:g}) lies far outside its {width}x{height} image")
        bottom = self.pixels_to_world_directions(np.array([[u, height - 1.0] for u in np.linspace(0, width - 1, 5)]))
        if np.all(bottom[:, 2] >= 0):
            doubts.append(f"{name} ({self.camera_height:.2f} m high, pitch {np.degrees(self.pitch):+.0f} degrees) "
                          "looks above the horizon at the bottom of its image: the floor where people stand is not in "
                          "view (positive pitch looks down)")
        elif np.degrees(self.pitch) < -LOOKS_UP_DEG:
            doubts.append(f"{name} looks {-np.degrees(self.pitch):.0f} degrees up from {self.camera_height:.2f} m: is "
                          "its pitch's sign right (positive looks down)? People are filmed from above or level")
        return (), tuple(doubts)

    def sees(self, points_world: np.ndarray) -> bool:
        """Whether every (..., 3) world point lies in front of the camera and projects inside the image."""
        pixels = self.project(np.asarray(points_world, dtype=np.float64).reshape(-1, 3))
        width, height = self.image_size
        return bool(np.all(np.isfinite(pixels)) and np.all((pixels >= 0) & (pixels <= [width - 1, height - 1])))

    def with_origin_at_height(self, height_m: float) -> Camera:
        """This camera in the world frame whose z = 0 lies ``height_m`` above this one's (x and y unchanged, every
        z smaller by ``height_m``): ``t + height_m R e_z``. A calibration made on a board on a table is the floor's
        camera with its origin raised; ``with_origin_at_height(floor_z)`` puts z = 0 back on a floor at ``floor_z``."""
        return dataclasses.replace(self, t=self.t + float(height_m) * self.R[:, 2])

    def in_floor_frame(self) -> Camera:
        """This camera, with its view, in the world frame of the floor below it, looking along +x (the frame of
        :meth:`from_height_pitch`, and the only one a camera estimated from a person can define)."""
        fx, fy, cx, cy = self.intrinsics
        return Camera.from_pose([0.0, 0.0, self.camera_height], 0.0, self.pitch, self.roll, fx, fy, cx, cy,
                                self.image_size, self.dist, self.name)

    def __repr__(self) -> str:
        fx, fy, cx, cy = self.intrinsics
        return (f"Camera({self.name or 'unnamed'}: f=({fx:.1f}, {fy:.1f}) c=({cx:.1f}, {cy:.1f}) "
                f"size={self.image_size} height={self.camera_height:.3f} m pitch={np.degrees(self.pitch):.2f} deg)")
