"""``Camera``: an immutable calibrated pinhole camera with OpenCV distortion, and its frame conversions (its
parameters, their checks and the forms they are written in: :mod:`ray3d.geometry.camera_parameters`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.geometry import transforms as tf
from ray3d.geometry.arrays import Array, check_points, like, namespace
from ray3d.geometry.camera_doubts import lens_doubts, view_doubts
from ray3d.geometry.camera_parameters import CameraParameters


def world_rays_to_height_plane(origin: Array, directions: Array, height_m: float) -> Array:
    """(3,) a world point and (..., 3) world directions of rays from it -> (..., 3) where each ray meets the
    horizontal plane ``z = height_m``; NaN where a ray never reaches it in front of ``origin``."""
    xp = namespace(directions)
    dz = directions[..., 2]
    # Solve C_z + s d_z = height for the ray parameter s; only s > 0 lies in front of the origin (the camera).
    s = (height_m - origin[2]) / xp.where(dz != 0, dz, xp.ones_like(dz))
    s = xp.where((dz != 0) & (s > 0) & xp.isfinite(s), s, xp.full_like(s, float("nan")))
    return origin + s[..., None] * directions


# Frozen like its parameters: nothing may be set on a camera after it is built.
@dataclasses.dataclass(frozen=True, eq=False)
class Camera(CameraParameters):
    """A calibrated camera (its fields, their checks and its constructors: :class:`CameraParameters`): what it
    does with world points, NCS points and pixels.

    Every method accepts numpy arrays or torch tensors of any leading shape and returns the same kind
    (torch keeps autograd and device).
    """

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
        directions = self.pixels_to_world_directions(pixels)
        return world_rays_to_height_plane(like(self.center, directions), directions, height_m)

    def doubts(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(what makes this camera unusable, what makes it implausible for people on a floor), each a clause naming
        the camera. Unusable: a lens whose distortion turns back inside the image (its rays cannot be recovered
        there). Implausible: a field of view across the image under 3 or over 170 degrees; a principal point more
        than an image's size outside it; an image whose lowest row looks above the horizon (the floor where
        people stand unseen); else an optical axis rising more than ``camera_doubts.LOOKS_UP_DEG`` (a pitch of the
        wrong sign)."""
        label = f"camera {self.name}" if self.name else "the camera"
        unusable, implausible = lens_doubts(label, self.intrinsics, self.dist, self.image_size)
        if unusable:
            return unusable, ()
        width, height = self.image_size
        bottom_row = np.array([[u, height - 1.0] for u in np.linspace(0, width - 1, 5)])
        view = view_doubts(label, self.camera_height, self.pitch, self.pixels_to_world_directions(bottom_row))
        return (), implausible + view

    def sees(self, points_world: np.ndarray) -> bool:
        """Whether every (..., 3) world point lies in front of the camera and projects inside the image."""
        pixels = self.project(np.asarray(points_world, dtype=np.float64).reshape(-1, 3))
        width, height = self.image_size
        return bool(np.all(np.isfinite(pixels)) and np.all((pixels >= 0) & (pixels <= [width - 1, height - 1])))

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
