"""``CameraBatch``: B calibrated cameras as arrays (B leading), one per sample: what the training data, the
networks, lifting and evaluation consume."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.camera import Camera

FIELDS = ("R", "t", "intrinsics", "dist", "height", "pitch", "roll")


@dataclasses.dataclass
class CameraBatch:
    """B cameras sharing one image size.

    R (B, 3, 3) world->camera rotations; t (B, 3) metres; intrinsics (B, 4) fx, fy, cx, cy; dist (B, 5) OpenCV
    k1, k2, p1, p2, k3; height (B,) metres above the floor, pitch (B,) and roll (B,) radians; image_size
    (width, height) pixels.
    """

    R: np.ndarray
    t: np.ndarray
    intrinsics: np.ndarray
    dist: np.ndarray
    height: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    image_size: tuple[int, int]

    def __len__(self) -> int:
        return len(self.t)

    @property
    def height_pitch(self) -> np.ndarray:
        """(B, 2) (height m, pitch rad): what the NCS and the camera embedding depend on."""
        return np.stack([self.height, self.pitch], -1)

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    def take(self, index) -> CameraBatch:
        """The cameras at ``index`` (a slice or an index array)."""
        return dataclasses.replace(self, **{f: getattr(self, f)[index] for f in FIELDS})

    @classmethod
    def from_cameras(cls, cams: list[Camera]) -> CameraBatch:
        if not cams:
            raise InputError("CameraBatch: no cameras")
        if len({c.image_size for c in cams}) > 1:
            raise InputError("CameraBatch: all cameras must share one image size")
        return cls(np.stack([c.R for c in cams]), np.stack([c.t for c in cams]),
                   np.stack([c.intrinsics for c in cams]), np.stack([c.dist for c in cams]),
                   np.array([c.camera_height for c in cams]), np.array([c.pitch for c in cams]),
                   np.array([c.roll for c in cams]), cams[0].image_size)

    @classmethod
    def repeated(cls, camera: Camera, count: int) -> CameraBatch:
        """The same camera ``count`` times (a sequence seen by one fixed camera)."""
        return cls.from_cameras([camera]).take(np.zeros(count, dtype=int))

    def camera(self, i: int, name: str = "") -> Camera:
        fx, fy, cx, cy = self.intrinsics[i]
        return Camera.from_intrinsics(fx, fy, cx, cy, self.dist[i], self.R[i], self.t[i], self.image_size, name)
