"""Falls read off a track's world joints: a sudden drop of the head, then lying on the floor, still."""

from __future__ import annotations

import numpy as np

from ray3d.body import HEAD, PELVIS, POSTURES, postures

# A fall: the head drops this far within this time, and within the next seconds the person lies on the floor
# (torso over 60 degrees from upright, pelvis this low) and stays put (the pelvis moves less than this) this long.
FALL_DROP_M, FALL_DROP_S = 1.0, 1.0
FALL_LYING_WITHIN_S, FALL_PELVIS_M, FALL_STILL_M, FALL_STILL_S = 2.0, 0.5, 0.5, 2.0
# The longest stretch of a track a fall takes to show (a causal monitor keeps this much of each person).
FALL_WINDOW_S = FALL_DROP_S + FALL_LYING_WITHIN_S + FALL_STILL_S + 1.0


def falls(times: np.ndarray, joints: np.ndarray) -> list[dict]:
    """(T,) seconds and (T, 17, 3) world joints of one track -> its falls: the head drops ``FALL_DROP_M`` within
    ``FALL_DROP_S``, the person then lies on the floor within ``FALL_LYING_WITHIN_S`` (torso over 60 degrees from
    upright, pelvis under ``FALL_PELVIS_M``) and stays there, the pelvis moving less than ``FALL_STILL_M``, for
    ``FALL_STILL_S``. Sitting down (the torso stays upright), bending (the pelvis stays up) and lying down slowly
    are not falls. Each with its time (when the head has dropped ``FALL_DROP_M``), place and evidence."""
    head, pelvis = joints[:, HEAD, 2], joints[:, PELVIS]
    down = (postures(joints) == POSTURES.index("lying")) & (pelvis[:, 2] < FALL_PELVIS_M)
    # The lowest the head gets within FALL_DROP_S after each frame (a reverse cumulative window minimum).
    horizon = np.searchsorted(times, times + FALL_DROP_S + 1e-9, side="right")  # up to FALL_DROP_S, rounding aside
    lowest_ahead = np.array([head[t + 1:end].min() if end > t + 1 else np.inf for t, end in enumerate(horizon)]) \
        if len(times) < 2 or np.ptp(np.diff(times)) > 1e-6 else _window_minimum(head, int(horizon[0]))
    found, resume = [], 0
    for t in np.flatnonzero(head - lowest_ahead >= FALL_DROP_M):
        if t < resume:
            continue
        window = np.arange(t + 1, horizon[t])
        landed = window[np.argmax(head[t] - head[window] >= FALL_DROP_M)]
        first, last = np.searchsorted(times, [times[landed], times[landed] + FALL_LYING_WITHIN_S], side="left")
        lying = first + np.flatnonzero(down[first:last + 1])
        if not len(lying):
            continue
        start = lying[0]
        stop = np.searchsorted(times, times[start] + FALL_STILL_S + 1e-9, side="right")
        still = np.arange(start, stop)
        spread = np.linalg.norm(pelvis[still, :2] - pelvis[start, :2], axis=-1).max()
        if times[still[-1]] - times[start] >= FALL_STILL_S - 1e-9 and down[still].all() and spread < FALL_STILL_M:
            found.append({"time_s": float(times[landed]), "place_m": pelvis[start, :2].round(3).tolist(),
                          "head_drop_m": round(float(head[t] - head[landed]), 3),
                          "drop_s": round(float(times[landed] - times[t]), 3),
                          "lying_from_s": float(times[start]), "still_m": round(float(spread), 3)})
            resume = stop  # one fall, not one per frame of it
    return found


def _window_minimum(values: np.ndarray, first_horizon: int) -> np.ndarray:
    """For evenly spaced frames: the minimum of the ``first_horizon - 1`` values after each (inf at the end, and
    everywhere when the horizon holds no later frame: frames further apart than it)."""
    size = first_horizon - 1
    if size < 1:
        return np.full(len(values), np.inf)
    after = np.append(values[1:], np.full(size, np.inf))
    return np.lib.stride_tricks.sliding_window_view(after, size).min(axis=1)[:len(values)]
