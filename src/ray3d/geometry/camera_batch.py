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
    """B cameras.

    R (B, 3, 3) world->camera rotations; t (B, 3) metres; intrinsics (B, 4) fx, fy, cx, cy; dist (B, 5) OpenCV
    k1, k2, p1, p2, k3; height (B,) metres above the floor, pitch (B,) and roll (B,) radians; image_size
    (width, height) pixels; image_sizes (B, 2) each camera's own where they differ (portrait and landscape
    training cameras), else None (every camera's is image_size).
    """

    R: np.ndarray
    t: np.ndarray
    intrinsics: np.ndarray
    dist: np.ndarray
    height: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    image_size: tuple[int, int]
    image_sizes: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.t)

    @property
    def height_pitch(self) -> np.ndarray:
        """(B, 2) (height m, pitch rad): what the NCS and the camera embedding depend on."""
        return np.stack([self.height, self.pitch], -1)

    @property
    def sizes(self) -> np.ndarray:
        """(B, 2) each camera's image (width, height) in pixels."""
        if self.image_sizes is not None:
            return self.image_sizes
        return np.broadcast_to(np.asarray(self.image_size, dtype=float), (len(self), 2))

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    def take(self, index) -> CameraBatch:
        """The cameras at ``index`` (a slice or an index array)."""
        sizes = None if self.image_sizes is None else self.image_sizes[index]
        return dataclasses.replace(self, image_sizes=sizes, **{f: getattr(self, f)[index] for f in FIELDS})

    @classmethod
    def scattered(cls, parts: list[tuple[np.ndarray, CameraBatch]], count: int) -> CameraBatch:
        """One batch of ``count`` cameras from ``parts``: (indices, cameras) pairs that place each part's cameras
        at its indices (together they cover 0..count-1 once); per-camera image sizes where the parts' differ."""
        first = parts[0][1]
        merged = {f: np.zeros((count, *getattr(first, f).shape[1:])) for f in FIELDS}
        sizes = np.zeros((count, 2))
        for indices, cameras in parts:
            for f in FIELDS:
                merged[f][indices] = getattr(cameras, f)
            sizes[indices] = cameras.sizes
        alike = bool(np.all(sizes == sizes[:1]))
        return cls(**merged, image_size=first.image_size if alike else tuple(int(v) for v in sizes[0]),
                   image_sizes=None if alike else sizes)

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
        size = self.image_size if self.image_sizes is None else tuple(int(v) for v in self.image_sizes[i])
        return Camera.from_intrinsics(fx, fy, cx, cy, self.dist[i], self.R[i], self.t[i], size, name)
