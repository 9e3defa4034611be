"""Two cameras on one clock: the time offset that best aligns the people both see at once.

Where a person is on the floor tells the offset without ambiguity but with each camera's depth bias (a bias
along a camera's ray passes for a time shift of a person walking along it); how their body moves about its
root (each step, each swing of a limb) tells it to a fraction of a frame, free of any bias, but a steady walk
looks alike one stride later. So the search is in two stages: the floor, the pelvis' bounce and the body together
pick the stride; then, within half a stride of it, the body and the shape of the path (the floor points less
their mean difference, which holds a constant bias: a turn, a change of pace) place the offset. How sure: the
spread of the same search over block-bootstrap draws of the shared frames."""

from __future__ import annotations

import numpy as np

from ray3d.errors import InputError
from ray3d.fusion.tracks import CameraTrack, on_clock, pair_distance
from ray3d.geometry.uncertainty import POSE_SD_M
from ray3d.io.world import World

BOUNCE_SD_M = 0.015   # how well two cameras agree on the pelvis' height about its mean
FINE_WINDOW_S = 0.25  # the body alone decides within this of the first stage's offset (half a stride or less)
FLOOR_IN_FINE = 0.1   # the floor's weight beside the body's in the second stage: enough to decide where the body
                      # stands still
MIN_SD_STEPS = 0.25  # the parabola's resolution: no offset is surer than a quarter of a step
BLOCK_S = 0.25        # the bootstrap's blocks: errors within one are alike


def _differences(a: CameraTrack, b: CameraTrack, centres: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, ...]:
    """The frames two tracks share (N,), and in each (N, 3) in squared sds: the Mahalanobis distance of their
    floor points, the difference of their pelvis heights about their means, and the mean difference of their
    bodies about their roots."""
    shared, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
    information = np.linalg.inv(a.floor_covariance(centres[0], rows_a) + b.floor_covariance(centres[1], rows_b))
    floor = a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2]
    height_a, height_b = a.joints[rows_a, 0, 2], b.joints[rows_b, 0, 2]
    about_a, about_b = (t.joints[r] - t.joints[r, :1] for t, r in ((a, rows_a), (b, rows_b)))
    return shared, np.column_stack([np.einsum("ni,nij,nj->n", floor, information, floor),
                                    ((height_a - height_a.mean() - height_b + height_b.mean()) / BOUNCE_SD_M) ** 2,
                                    ((about_a - about_b) ** 2).sum(axis=-1).mean(axis=-1) / POSE_SD_M ** 2])


def _best_shift(steps: np.ndarray, scores: np.ndarray) -> float:
    """The step of the lowest score, refined to a fraction of a step by a parabola through the best three."""
    best = int(np.argmin(scores))
    if 0 < best < len(steps) - 1 and np.isfinite(scores[best - 1:best + 2]).all():
        left, middle, right = scores[best - 1:best + 2]
        if left - 2 * middle + right > 0:
            return float(steps[best] + 0.5 * (left - right) / (left - 2 * middle + right))
    return float(steps[best])


def find_time_offset(reference: World, other: World, max_offset_s: float = 2.0,
                     resamples: int = 200) -> tuple[float, float]:
    """The offset (seconds; ``other``'s frame f happens at f / fps - offset on the reference's clock) that best
    aligns the people both cameras see at once (each pair of tracks whose floor places agree), searched in steps
    of a frame of the reference within +-``max_offset_s`` and refined to a fraction of a frame (see the module's
    note); and its standard deviation over ``resamples`` block-bootstrap draws (a person standing still gives
    the clock little to go by). Refused when no shift lets the cameras share a person."""
    fps = reference.fps
    steps = np.arange(-int(round(max_offset_s * fps)), int(round(max_offset_s * fps)) + 1)
    first = on_clock(reference, 0, 0.0, fps)
    centres = (reference.camera.center[:2], other.camera.center[:2])
    block = max(1, int(round(BLOCK_S * fps)))
    per_step: list[dict] = []  # per step: {(track, track, block): (floor, bounce and body sums, frames)}
    for step in steps:
        sums: dict = {}
        for a in first:
            for b in on_clock(other, 1, step / fps, fps):
                distance, allowed, _ = pair_distance(a, b, fps)
                if distance <= 2 * allowed:
                    frames, differences = _differences(a, b, centres)
                    for key in np.unique(frames // block):
                        inside = frames // block == key
                        sums[(a.name, b.name, int(key))] = (*differences[inside].sum(axis=0), inside.sum())
        per_step.append(sums)
    keys = sorted(set().union(*per_step), key=str)
    if not keys:
        raise InputError("cameras: no person is seen by both at once at any offset within "
                         f"{max_offset_s:g} s; give the offset", ("offsets",))
    # (steps, blocks, 4): each block's sums at each step (0 where the block is not shared at that step)
    table = np.array([[sums.get(k, (0.0, 0.0, 0.0, 0)) for k in keys] for sums in per_step], dtype=np.float64)
    fine = int(round(FINE_WINDOW_S * fps))

    def search(weights: np.ndarray) -> float:
        floor, bounce, body, frames = np.einsum("skc,k->cs", table, weights)
        shared = frames > 0
        stride = int(np.argmin(np.where(shared, (floor + bounce + body) / np.maximum(frames, 1), np.inf)))
        window = slice(max(0, stride - fine), stride + fine + 1)
        fine_score = (FLOOR_IN_FINE * floor + body) / np.maximum(frames, 1)
        return _best_shift(steps[window], np.where(shared, fine_score, np.inf)[window])

    rng = np.random.default_rng(0)
    draws = [search(rng.multinomial(len(keys), np.full(len(keys), 1 / len(keys))).astype(np.float64))
             for _ in range(resamples)]
    return search(np.ones(len(keys))) / fps, max(float(np.std(draws)), MIN_SD_STEPS) / fps
