"""Body measures: how tall people are, where the points of a standing person's vertical axis lie as fractions
of their stature, and the size chain the refinement keeps constant. Every module that needs a body figure reads
it here; ``tests/test_architecture.py`` refuses a second copy of these numbers.

Heights are measured on the training performers of the shipped mocap (upright frames, relative to the head
joint) and scaled by the head joint's height, 0.94 of stature (shoulders at 0.818 of stature, Drillis & Contini
1966); the size chain's prior is its spread over the same performers.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.skeleton import H36M17

ADULT_STATURE_M = 1.70       # the person a prior imagines when nothing else is known
ADULT_STATURE_SD_M = 0.07
PLAUSIBLE_STATURE_M = (0.8, 2.3)  # a small child to the tallest adults; outside it, no person
# Heights above the floor, as fractions of stature, of the points on a standing person's vertical axis: the
# mid-ankle, the pelvis, the thorax and the H36M head joint.
AXIS_HEIGHTS = {"ankles": 0.067, "pelvis": 0.525, "thorax": 0.851, "head": 0.940}
AXIS_JOINTS = {"ankles": ("l_ankle", "r_ankle"), "pelvis": ("pelvis",), "thorax": ("thorax",), "head": ("head",)}
# The head joint's height over the lowest ankle as a fraction of stature.
HEAD_OVER_ANKLE_OF_STATURE = AXIS_HEIGHTS["head"] - AXIS_HEIGHTS["ankles"]

# The lowest ankle joint of a planted foot stands this high above the floor (0.069 m on the training performers,
# interquartile 0.049-0.109 m; each performer's mocap is grounded to it, ``ray3d.data.motion.ground_performers``).
PLANTED_ANKLE_HEIGHT_M = 0.07
# Where a keypoint detector puts joints against the mocap's joint centres, metres in the body frame (outward, forward,
# up), measured on real-near (OpenPose BODY25 keypoints triangulated from four views, against the training
# performers at the same stature: docs/RESULTS.md, "Trained for the cameras people use"): the hips 0.065 m higher and
# 0.007 m wider, the knees 0.03 m and the ankles 0.05 m higher (the ankle keypoint of a planted, shod foot stands
# 0.12-0.14 m up).
DETECTOR_JOINT_OFFSETS_M = {"hip": (0.007, 0.0, 0.065), "knee": (0.0, 0.0, 0.03), "ankle": (0.0, 0.0, 0.05)}
# How high a detector's ankle keypoint of a planted foot stands: the rays a detector gives pass there.
DETECTOR_PLANTED_ANKLE_HEIGHT_M = PLANTED_ANKLE_HEIGHT_M + DETECTOR_JOINT_OFFSETS_M["ankle"][2]
# How far one detector's mid-hips stand from another's (or a skeleton's pelvis) on the floor plan, per axis:
# BlazePose's lifted hips against real-near's triangulated OpenPose hips err 0.01-0.07 m across the ray by view
# (docs/RESULTS.md, "Where people stand, observed").
DETECTOR_ROOT_DEFINITION_SD_M = 0.04

HEAD, PELVIS = H36M17.index("head"), H36M17.index("pelvis")
ANKLES = (H36M17.index("l_ankle"), H36M17.index("r_ankle"))
# The chain whose length measures a body's size: thorax to pelvis along the spine, plus the mean leg (the head
# and neck are left out: detectors place them least like the mocap does). 1.34 m on the training performers
# (5-95 %: 1.26-1.52 m).
TRUNK_CHAIN = ("thorax", "spine", "pelvis")
LEGS = (("l_hip", "l_knee", "l_ankle"), ("r_hip", "r_knee", "r_ankle"))
ADULT_BODY_SIZE_M = 1.36
ADULT_BODY_SIZE_SD = 0.12    # relative
# The size chain a detector's keypoints give an adult of the prior's size: its hips stand higher (a shorter trunk,
# longer thighs), its knees and ankles too (shorter shins), by ``DETECTOR_JOINT_OFFSETS_M``: 1.31 m.
_RAISED = {joint: offset[2] for joint, offset in DETECTOR_JOINT_OFFSETS_M.items()}
DETECTOR_BODY_SIZE_M = (ADULT_BODY_SIZE_M - _RAISED["hip"] + (_RAISED["hip"] - _RAISED["knee"])
                        + (_RAISED["knee"] - _RAISED["ankle"]))
@dataclasses.dataclass(frozen=True)
class KeypointSource:
    """How one kind of keypoints stands a person on the floor, shared by everybody it sees (what many people do not
    average away): its ankle keypoint of a planted, shod foot stands ``planted_ankle_m`` +/- ``planted_ankle_sd_m``
    over the floor (where its ankle rays meet the floor), while the refined pose's lowest ankle, the network's
    drawn only part of the way to those rays, rests ``pose_ankle_m`` over it; it gives an adult of the prior's size a
    size chain of ``body_size_m``, and the network's pose on its keypoints' rays reads that adult's size chain as
    ``read_size_m`` (what people's sizes tell of the floor from), known to a relative ``read_size_sd``."""

    planted_ankle_m: float
    planted_ankle_sd_m: float
    pose_ankle_m: float
    body_size_m: float
    read_size_m: float
    read_size_sd: float


# A site's people against the prior's mean size (a population 4 % taller or shorter is common), in log size.
POPULATION_SIZE_SD = 0.035
# The size chain ``ray3d-real``'s pose on a detector's keypoints reads for an adult of the prior's size: on
# MediaPipe BlazePose's keypoints 1.28 m (``vtest.avi``'s 23 people, 431 s of them standing, put the floor where its
# true camera's z = 0 is with it, if they are of the prior's mean size: docs/RESULTS.md "The floor on evidence"), on
# the benchmarks' emulated detector 1.385 m (``level-test``, 54 cameras, ten people each, seed 1); another
# detector's, between them.
BLAZEPOSE_READ_SIZE_M = 1.28
EMULATED_READ_SIZE_M = 1.385
# Measured per detector: the mocap's joints (exact 2D: the training performers' own); MediaPipe BlazePose's planted
# ankles triangulated from real-near's four views, 0.149 m up (docs/RESULTS.md, "Where people stand, observed");
# OpenPose BODY-25's about 0.10 m on an indoor recording (issue 66) and 0.12-0.14 m on real-near; other detectors'
# layouts (COCO-17 from any of several) the mean offsets above, known less well.
# The refined pose's lowest ankle rests at ``DETECTOR_PLANTED_ANKLE_HEIGHT_M`` for every detector (on real-near's
# BlazePose keypoints, whose rays meet the floor 0.149 m up, it halved the pelvis's floor error; 0.149 doubled it).
KEYPOINT_SOURCES = {
    "h36m17": KeypointSource(PLANTED_ANKLE_HEIGHT_M, 0.01, PLANTED_ANKLE_HEIGHT_M, ADULT_BODY_SIZE_M,
                             ADULT_BODY_SIZE_M, 0.02),
    "blazepose33": KeypointSource(0.149, 0.015, DETECTOR_PLANTED_ANKLE_HEIGHT_M, DETECTOR_BODY_SIZE_M,
                                  BLAZEPOSE_READ_SIZE_M, 0.03),
    **{layout: KeypointSource(ankle, ankle_sd, DETECTOR_PLANTED_ANKLE_HEIGHT_M, DETECTOR_BODY_SIZE_M,
                              (BLAZEPOSE_READ_SIZE_M + EMULATED_READ_SIZE_M) / 2, 0.04)
       for layout, ankle, ankle_sd in (("body25", 0.11, 0.02), ("coco17", DETECTOR_PLANTED_ANKLE_HEIGHT_M, 0.025),
                                       ("halpe26", DETECTOR_PLANTED_ANKLE_HEIGHT_M, 0.025))},
}
# The emulated detector of the benchmarks (``data.samples.DETECTOR_JOINT_OFFSETS_M`` scaled 0.5-1.5 per person),
# whatever layout it reports.
EMULATED_DETECTOR = KeypointSource(DETECTOR_PLANTED_ANKLE_HEIGHT_M, 0.025, DETECTOR_PLANTED_ANKLE_HEIGHT_M,
                                   DETECTOR_BODY_SIZE_M, EMULATED_READ_SIZE_M, 0.03)


def keypoint_source(layout: str) -> KeypointSource:
    """The ``KeypointSource`` of keypoints in ``layout`` (a layout name); an unknown detector's is COCO-17's."""
    return KEYPOINT_SOURCES.get(layout, KEYPOINT_SOURCES["coco17"])



# An upright person's head joint stands this many times their size chain over the floor.
HEAD_HEIGHT_OF_BODY_SIZE = AXIS_HEIGHTS["head"] * ADULT_STATURE_M / ADULT_BODY_SIZE_M


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


def stature(joints: np.ndarray, upright: np.ndarray | None = None, ankle_raised_m: float = 0.0) -> float:
    """(T, 17, 3) H36M-17 world joints of one person -> their stature in metres: the median head-over-ankle
    height of the ``upright`` frames (default: all) over ``HEAD_OVER_ANKLE_OF_STATURE``; NaN without frames.
    ``ankle_raised_m``: how much higher than the mocap's ankle joint the joints' ankles stand (a detector's
    ankle keypoint: ``DETECTOR_JOINT_OFFSETS_M``)."""
    heights = head_over_ankle(np.asarray(joints, dtype=np.float64)) + ankle_raised_m
    heights = heights if upright is None else heights[np.asarray(upright, dtype=bool)]
    return float(np.median(heights) / HEAD_OVER_ANKLE_OF_STATURE) if len(heights) else float("nan")


def lowest_ankles(joints: np.ndarray) -> np.ndarray:
    """(T, 17, 3) -> (T, 3) the lower of the two ankle joints of each frame."""
    lower = np.argmin(joints[:, list(ANKLES), 2], axis=1)
    return joints[np.arange(len(joints)), np.array(ANKLES)[lower]]


POSTURES = ("upright", "sitting or crouching", "lying", "airborne")
# A torso (pelvis to thorax) leaning further than this from the vertical is lying; a pelvis lower than this over
# the lowest ankle is sitting or crouching (an adult's stands 0.75-0.85 m over it, a seated one's 0.3-0.5 m); a
# lowest ankle this far over where the feet rest is airborne (a jump, a foot on a step).
LYING_TORSO_DEG = 60.0
SITTING_PELVIS_M = 0.55
AIRBORNE_ANKLE_M = 0.2


def postures(joints: np.ndarray, floor_height: float | np.ndarray = 0.0) -> np.ndarray:
    """(T, 17, 3) H36M-17 world joints (z up) -> (T,) indices into ``POSTURES`` from the 3D pose: lying (torso
    near horizontal), sitting or crouching (pelvis low over the feet), airborne (lowest ankle well above the
    ``floor_height`` plus a planted ankle's height), else upright."""
    joints = np.asarray(joints, dtype=np.float64)
    torso = joints[:, H36M17.index("thorax")] - joints[:, PELVIS]
    tilt = np.degrees(np.arccos(np.clip(torso[:, 2] / np.maximum(np.linalg.norm(torso, axis=-1), 1e-9), -1, 1)))
    lowest = lowest_ankle_height(joints)
    classes = np.zeros(len(joints), dtype=int)
    classes[lowest - floor_height - PLANTED_ANKLE_HEIGHT_M > AIRBORNE_ANKLE_M] = POSTURES.index("airborne")
    classes[joints[:, PELVIS, 2] - lowest < SITTING_PELVIS_M] = POSTURES.index("sitting or crouching")
    classes[tilt > LYING_TORSO_DEG] = POSTURES.index("lying")
    return classes
