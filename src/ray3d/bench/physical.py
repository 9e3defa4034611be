"""Physical checks of lifted people, for footage without ground truth: does each person stand on the floor, have
a human stature and bone lengths that stay put, walk at a human speed, plant their feet without skating, and
move without jitter? Only frames the detector saw count (not the ones filled in across gaps)."""

from __future__ import annotations

import numpy as np

from ray3d.body import ANKLES, head_over_ankle, lowest_ankle_height, stature
from ray3d.io.world import LiftResult
from ray3d.skeleton import H36M17
from ray3d.temporal import seen_frames

FLOOR_BAND_M = (-0.10, 0.25)     # where the lowest ankle of a person standing on the floor may be
PLANTED_BAND_M = 0.05            # a foot within this of the track's low ankle height counts as planted
CHECKS = ("frames", "ankle_on_floor_fraction", "lowest_ankle_median_m", "head_over_ankle_m", "stature_m",
          "walking_speed_1s_m_s", "speed_p90_m_s", "bone_length_cv", "foot_skating_m_s", "jitter_m_s2")


def track_checks(result: LiftResult) -> dict[str, float]:
    """The checks of one track (see ``CHECKS``); speeds over the observed frames only."""
    seen = seen_frames(result.interpolated)
    joints, fps = result.joints[seen], result.fps
    frames = result.frames[seen]
    lowest = lowest_ankle_height(joints)
    # Consecutive observed frames give speeds; a window of about a second gives the walking speed.
    step = np.diff(frames)
    consecutive = step == 1
    pelvis = joints[:, 0, :2]
    speed = np.linalg.norm(np.diff(pelvis, axis=0), axis=-1)[consecutive] * fps
    second = max(int(round(fps)), 1)
    index = {f: i for i, f in enumerate(frames)}
    pairs = [(i, index[f + second]) for i, f in enumerate(frames) if f + second in index]
    walking = np.array([np.linalg.norm(pelvis[j] - pelvis[i]) for i, j in pairs]) * fps / second
    bones = np.stack([np.linalg.norm(joints[:, j] - joints[:, p], axis=-1)
                      for j, p in enumerate(H36M17.parents) if p >= 0], axis=1)
    lower = np.take_along_axis(joints[:, ANKLES], joints[:, ANKLES, 2].argmin(1)[:, None, None], axis=1)[:, 0]
    planted = (lowest <= np.percentile(lowest, 10) + PLANTED_BAND_M)[1:] & consecutive
    skating = np.linalg.norm(np.diff(lower[:, :2], axis=0), axis=-1)[planted] * fps
    triples = consecutive[1:] & consecutive[:-1]
    acceleration = np.linalg.norm(np.diff(joints, 2, axis=0), axis=-1)[triples] * fps ** 2

    def median(values: np.ndarray) -> float:
        return float(np.median(values)) if len(values) else float("nan")

    return {"frames": int(seen.sum()),
            "ankle_on_floor_fraction": float(np.mean((lowest >= FLOOR_BAND_M[0]) & (lowest <= FLOOR_BAND_M[1]))),
            "lowest_ankle_median_m": median(lowest), "head_over_ankle_m": median(head_over_ankle(joints)),
            "stature_m": stature(joints),
            "walking_speed_1s_m_s": median(walking),
            "speed_p90_m_s": float(np.percentile(speed, 90)) if len(speed) else float("nan"),
            "bone_length_cv": float(np.mean(bones.std(0) / bones.mean(0))),
            "foot_skating_m_s": median(skating), "jitter_m_s2": median(acceleration.ravel())}


def summarise(rows: list[dict[str, float]]) -> dict[str, float]:
    """Frame-weighted mean of the fraction, medians over tracks of the rest."""
    frames = np.array([r["frames"] for r in rows], dtype=float)
    summary = {"tracks": len(rows), "frames": int(frames.sum()),
               "ankle_on_floor_fraction": float(np.average([r["ankle_on_floor_fraction"] for r in rows],
                                                           weights=frames))}
    for key in CHECKS[2:]:
        summary[key] = float(np.nanmedian([r[key] for r in rows]))
    return summary
