"""Where a person stands, and how sure that is: the one record of it (``Positioned``: joints and the root's
standard deviation along and across the camera's ray through it, for a person over time, now, or on a fused
clock) and the ray-shaped covariances it implies, which fusing several cameras' answers weighs by
(``information_weighted``)."""

from __future__ import annotations

import dataclasses

import numpy as np

POSE_SD_M = 0.04      # a lifted joint's error about the person's root, each axis
UNKNOWN_SD_M = (0.3, 0.05)  # the root's sd along and across its ray taken where none is stated


def along_ray(points: np.ndarray, centre: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """(..., D, D) covariances of (..., D) points seen from ``centre``: ``sd[..., 0]`` along the ray to each point,
    ``sd[..., 1]`` across it."""
    ray = points - centre
    ray /= np.maximum(np.linalg.norm(ray, axis=-1, keepdims=True), 1e-9)
    along = ray[..., :, None] * ray[..., None, :]
    return (sd[..., 0, None, None] ** 2 * along
            + sd[..., 1, None, None] ** 2 * (np.eye(points.shape[-1]) - along))


def joint_covariances(joints: np.ndarray, sd: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(..., J, 3, 3) each of the (..., J, 3) joints' covariance from a camera at ``centre``: long along the
    joint's own ray (by the root's sd along its ray, ``sd`` (..., 2)) and narrow across it (the root's sd
    across), plus the pose's own error."""
    along_and_across = np.repeat(np.asarray(sd)[..., None, :], joints.shape[-2], axis=-2)
    return along_ray(joints, centre, along_and_across) + POSE_SD_M ** 2 * np.eye(3)


def root_spread(covariance: np.ndarray) -> np.ndarray:
    """(..., 2) the largest and the smallest sd of the root's floor point under (..., J, 3, 3) joint covariances
    (as a camera's answer states its root's sd along and across its ray)."""
    return np.sqrt(np.clip(np.linalg.eigvalsh(covariance[..., 0, :2, :2]), 0.0, None))[..., ::-1].copy()


def information_weighted(joints: np.ndarray, covariances: np.ndarray,
                         seen: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """N cameras' answers (N, ..., 3) with their covariances (N, ..., 3, 3) -> the information-weighted mean
    (..., 3) and its covariance (..., 3, 3); ``seen`` (N, ...) says which answers there are (all by default). The
    one fusion of several cameras' joints, offline (``fusion.fuse``) and live (``fusion.live``)."""
    information = np.linalg.inv(covariances)
    if seen is not None:
        information = information * seen[..., None, None]
    covariance = np.linalg.inv(information.sum(axis=0))
    weighted = np.einsum("n...ij,n...j->...i", information, np.nan_to_num(joints))
    return np.einsum("...ij,...j->...i", covariance, weighted), covariance


class Positioned:
    """A person's world joints ``joints`` (..., J, 3) with ``position_sd`` (..., 2), the root's standard deviation
    along the camera's ray through it and across that ray (None: not stated). The one record of where a person
    stands and how sure that is: a person over time (``io.world.LiftResult``), now (``PersonNow``, below), one
    camera's track on a shared clock (``fusion.tracks.CameraTrack``). ``rows`` selects along the first axis."""

    joints: np.ndarray
    position_sd: np.ndarray | None

    @property
    def root(self) -> np.ndarray:
        """(..., 3) the pelvis: where the person stands on the floor plan, and how high."""
        return self.joints[..., 0, :]

    def stated_sd(self, rows=slice(None)) -> np.ndarray:
        """(..., 2) the root's sd along and across its ray, ``UNKNOWN_SD_M`` where none is stated."""
        sd = np.broadcast_to(np.nan, self.joints.shape[:-2] + (2,)) if self.position_sd is None else self.position_sd
        sd = np.asarray(sd)[rows]
        return np.where(np.isfinite(sd), sd, UNKNOWN_SD_M)

    def joint_covariances(self, centre: np.ndarray, rows=slice(None)) -> np.ndarray:
        """(..., J, 3, 3) every joint's covariance as a camera at ``centre`` sees it (``joint_covariances``)."""
        return joint_covariances(self.joints[rows], self.stated_sd(rows), centre)

    def floor_covariance(self, centre: np.ndarray, rows=slice(None)) -> np.ndarray:
        """(..., 2, 2) the root's floor point's covariance from a camera at ``centre`` (its floor point): long
        along the ray, narrow across it."""
        return along_ray(self.joints[rows][..., 0, :2], np.asarray(centre)[:2], self.stated_sd(rows))


@dataclasses.dataclass(frozen=True)
class PersonNow(Positioned):
    """One person in the frame a live run just processed: their track id, world joints (17, 3), the root's
    standard deviation along and across its ray (2,), their stature so far (None before the first refinement),
    where their camera's tracker placed them on the floor and how it read their walk (``tracked``: (4,) x, y, the
    point between the ankles, and vx, vy in m/s) and their clothes' colours as it holds them (``clothes``: its
    histogram); both None for a person fused from several cameras."""

    track: str
    joints: np.ndarray
    position_sd: np.ndarray
    stature_m: float | None
    tracked: np.ndarray | None = None
    clothes: np.ndarray | None = None
