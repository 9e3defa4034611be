"""Pose metrics (brief section 5) for numpy and torch, in the input's units (multiply metres by 1000 for mm).

Every metric takes predictions and ground truth of shape (..., J, 3) and returns the mean over all frames, or
with ``reduction="none"`` one value per frame (shape (...)), ready for :func:`grouped_mean`. Two worlds of one
scene are compared track by track with :func:`match_tracks`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Hashable, Sequence

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.arrays import Array, as_float, namespace, to_numpy

ROOT = 0


def _pair(predicted: Array, target: Array) -> tuple[Array, Array]:
    predicted, target = as_float(predicted), as_float(target)
    if predicted.shape != target.shape or predicted.ndim < 2:
        raise InputError(f"metrics: predicted {tuple(predicted.shape)} and target {tuple(target.shape)} must "
                         "have the same shape (..., J, 3)")
    return predicted, target


def _reduce(per_frame: Array, reduction: str) -> Array:
    if reduction == "none":
        return per_frame
    if reduction == "mean":
        return per_frame.mean()
    raise InputError(f"metrics: reduction must be 'mean' or 'none', got {reduction!r}")


def _joint_distance(a: Array, b: Array) -> Array:
    d = a - b
    return np.linalg.norm(d, axis=-1) if isinstance(d, np.ndarray) else d.norm(dim=-1)


def abs_mpjpe(predicted: Array, target: Array, reduction: str = "mean") -> Array:
    """Absolute MPJPE: mean joint distance in the world frame, no alignment."""
    predicted, target = _pair(predicted, target)
    return _reduce(_joint_distance(predicted, target).mean(-1), reduction)


def mpjpe(predicted: Array, target: Array, reduction: str = "mean") -> Array:
    """MPJPE: mean joint distance after subtracting each pose's root (joint 0) from it."""
    predicted, target = _pair(predicted, target)
    return abs_mpjpe(predicted - predicted[..., ROOT:ROOT + 1, :], target - target[..., ROOT:ROOT + 1, :], reduction)


def mrpe(predicted: Array, target: Array, reduction: str = "mean") -> Array:
    """MRPE: distance of the root joint (joint 0 only) in the world frame."""
    predicted, target = _pair(predicted, target)
    return _reduce(_joint_distance(predicted[..., ROOT, :], target[..., ROOT, :]), reduction)


def procrustes_align(predicted: Array, target: Array) -> Array:
    """Align each (..., J, 3) pose to its target by the best similarity (scale, rotation, translation).

    Least squares (Umeyama); reflections are excluded so the result is a proper rotation.
    """
    predicted, target = _pair(predicted, target)
    xp = namespace(predicted)
    mu_p, mu_t = predicted.mean(-2, keepdims=True), target.mean(-2, keepdims=True)
    p, t = predicted - mu_p, target - mu_t
    covariance = p.swapaxes(-1, -2) @ t  # (..., 3, 3)
    u, s, vt = xp.linalg.svd(covariance)
    # Flip the last singular direction where u v^T would be a reflection.
    det_sign = xp.sign(xp.linalg.det(u @ vt))
    correction = xp.ones_like(s)
    correction[..., -1] = det_sign
    s = s * correction
    u = u * correction[..., None, :]
    rotation = u @ vt  # maps rows: p @ rotation ~ t
    variance = (p * p).sum((-1, -2))
    scale = s.sum(-1) / xp.where(variance > 0, variance, xp.ones_like(variance))
    return scale[..., None, None] * (p @ rotation) + mu_t


def p_mpjpe(predicted: Array, target: Array, reduction: str = "mean") -> Array:
    """P-MPJPE: MPJPE after per-frame similarity Procrustes alignment to the target."""
    return abs_mpjpe(procrustes_align(predicted, target), as_float(target), reduction)


def mpjve(predicted: Array, target: Array, reduction: str = "mean") -> Array:
    """MPJVE: mean joint distance between frame-to-frame velocities; time is axis -3, so (..., T, J, 3) gives
    (..., T - 1) values. Units per frame (multiply by fps for per second)."""
    predicted, target = _pair(predicted, target)
    if predicted.ndim < 3 or predicted.shape[-3] < 2:
        raise InputError(f"mpjve: need (..., T, J, 3) with T >= 2, got {tuple(predicted.shape)}")
    velocity_p = predicted[..., 1:, :, :] - predicted[..., :-1, :, :]
    velocity_t = target[..., 1:, :, :] - target[..., :-1, :, :]
    return abs_mpjpe(velocity_p, velocity_t, reduction)


def root_error_in_sds(predicted: np.ndarray, target: np.ndarray, position_sd: np.ndarray,
                      camera) -> np.ndarray:
    """(T, 17, 3) predicted and true world joints, (T, 2) the root's reported sd along its ray and across it, as
    seen by ``camera`` (a ``Camera``) -> (T, 2) the root's error in those standard deviations: along the ray, and
    across it in the floor plane (each one axis, so that a calibrated sd holds 68 % of frames within 1 sd)."""
    ray = predicted[:, 0] - camera.center
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    side = np.cross(ray, [0.0, 0.0, 1.0])
    side /= np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-12)
    error = target[:, 0] - predicted[:, 0]
    return np.abs(np.stack([np.einsum("ti,ti->t", error, ray), np.einsum("ti,ti->t", error, side)], axis=-1)) \
        / position_sd


def grouped_mean(per_frame: Array, groups: Sequence[Hashable]) -> tuple[float, dict[Hashable, float]]:
    """Average per-frame values within each group (frame-weighted), then over groups (each group equal).

    This is the Human3.6M protocol's "average over actions"; use it per action, per camera or per clip.

    Returns:
        (mean over groups, {group: mean within group}) with groups in order of first appearance.
    """
    values = to_numpy(per_frame).astype(np.float64).reshape(-1)
    if len(groups) != len(values):
        raise InputError(f"grouped_mean: {len(values)} values but {len(groups)} group labels")
    if len(values) == 0:
        raise InputError("grouped_mean: no values")
    by_group: dict[Hashable, list[int]] = {}
    for i, g in enumerate(groups):
        by_group.setdefault(g, []).append(i)
    means = {g: float(values[idx].mean()) for g, idx in by_group.items()}
    return float(np.mean(list(means.values()))), means


@dataclasses.dataclass(frozen=True)
class TrackMatch:
    """A track of one world matched to a track of another world of the same scene: their names, the frames both
    have and the distance between their pelvis floor points in each (m)."""

    first: Hashable
    second: Hashable
    frames: np.ndarray
    distances_m: np.ndarray

    @property
    def median_m(self) -> float:
        return float(np.median(self.distances_m))


def match_tracks(first: dict, second: dict, min_share: float = 0.0, within_m: float = np.inf) -> list[TrackMatch]:
    """Each track of ``first`` matched to the track of ``second`` whose pelvis floor points lie nearest (median
    over the frames both have), among those sharing at least ``min_share`` of its frames (at least one) and
    within ``within_m``; tracks without such a partner are left out. Tracks are {name: track}, each with
    ``frames`` (N,) and ``root`` (N, 3) on one clock and in one frame of reference (two worlds' ``in_frame("world")``).
    Several tracks of ``first`` may match one of ``second`` (a track broken in two where the other is whole)."""
    matches = []
    for name, track in first.items():
        candidates = []
        for other_name, other in second.items():
            shared, rows, other_rows = np.intersect1d(track.frames, other.frames, return_indices=True)
            if len(shared) == 0 or len(shared) < min_share * len(track.frames):
                continue
            distances = np.linalg.norm(track.root[rows, :2] - other.root[other_rows, :2], axis=-1)
            candidates.append(TrackMatch(name, other_name, shared, distances))
        nearest = min(candidates, key=lambda match: match.median_m, default=None)
        if nearest is not None and nearest.median_m <= within_m:
            matches.append(nearest)
    return matches
