"""Body measures: how tall people are, where the points of a standing person's vertical axis lie as fractions
of their stature, and the size chain the refinement keeps constant. Every module that needs a body figure reads
it here; ``tests/test_architecture.py`` refuses a second copy of these numbers.

Heights are measured on the training performers of the shipped mocap (upright frames, relative to the head
joint) and scaled by the head joint's height, 0.94 of stature (shoulders at 0.818 of stature, Drillis & Contini
1966); the size chain's prior is its spread over the same performers.
"""

from __future__ import annotations

import numpy as np

from ray3d.skeleton import H36M17

ADULT_STATURE_M = 1.70       # the person a prior imagines when nothing else is known
ADULT_STATURE_SD_M = 0.07
# Heights above the floor, as fractions of stature, of the points on a standing person's vertical axis: the
# mid-ankle, the pelvis, the thorax and the H36M head joint.
AXIS_HEIGHTS = {"ankles": 0.067, "pelvis": 0.525, "thorax": 0.851, "head": 0.940}
AXIS_JOINTS = {"ankles": ("l_ankle", "r_ankle"), "pelvis": ("pelvis",), "thorax": ("thorax",), "head": ("head",)}
# The head joint's height over the lowest ankle as a fraction of stature.
HEAD_OVER_ANKLE_OF_STATURE = AXIS_HEIGHTS["head"] - AXIS_HEIGHTS["ankles"]

# The lowest ankle joint of a planted foot stands this high above the floor (0.069 m on the training performers,
# interquartile 0.049-0.109 m).
PLANTED_ANKLE_HEIGHT_M = 0.07

HEAD, PELVIS = H36M17.index("head"), H36M17.index("pelvis")
ANKLES = (H36M17.index("l_ankle"), H36M17.index("r_ankle"))
# The chain whose length measures a body's size: thorax to pelvis along the spine, plus the mean leg (the head
# and neck are left out: detectors place them least like the mocap does). 1.34 m on the training performers
# (5-95 %: 1.26-1.52 m).
TRUNK_CHAIN = ("thorax", "spine", "pelvis")
LEGS = (("l_hip", "l_knee", "l_ankle"), ("r_hip", "r_knee", "r_ankle"))
ADULT_BODY_SIZE_M = 1.36
ADULT_BODY_SIZE_SD = 0.12    # relative


def body_sizes(joints: np.ndarray) -> np.ndarray:
    """(..., 17, 3) H36M-17 joints -> (...) the length of the size chain (trunk plus the mean leg), metres."""
    def chain(names) -> np.ndarray:
        points = joints[..., [H36M17.index(n) for n in names], :]
        return np.linalg.norm(np.diff(points, axis=-2), axis=-1).sum(-1)

    return chain(TRUNK_CHAIN) + (chain(LEGS[0]) + chain(LEGS[1])) / 2


def lowest_ankle_height(joints: np.ndarray) -> np.ndarray:
    """(..., 17, 3) H36M-17 world joints (z up) -> (...) the height of the lower ankle."""
    return joints[..., ANKLES, 2].min(-1)


def head_over_ankle(joints: np.ndarray) -> np.ndarray:
    """(..., 17, 3) H36M-17 world joints (z up) -> (...) the head joint's height over the lower ankle."""
    return joints[..., HEAD, 2] - lowest_ankle_height(joints)


def stature(joints: np.ndarray, upright: np.ndarray | None = None) -> float:
    """(T, 17, 3) H36M-17 world joints of one person -> their stature in metres: the median head-over-ankle
    height of the ``upright`` frames (default: all) over ``HEAD_OVER_ANKLE_OF_STATURE``; NaN without frames."""
    heights = head_over_ankle(np.asarray(joints, dtype=np.float64))
    heights = heights if upright is None else heights[np.asarray(upright, dtype=bool)]
    return float(np.median(heights) / HEAD_OVER_ANKLE_OF_STATURE) if len(heights) else float("nan")
