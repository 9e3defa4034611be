"""Keypoints as real detectors put them, from mocap: each joint moved by the offsets measured between a detector's
keypoints and the mocap's joints (``body.DETECTOR_JOINT_OFFSETS_M``, along the body's own axes), the face points
detectors measure and the mocap lacks, and the joints a detector misses (hidden behind the body or an occluder)
stood in for. What training samples (``data.samples``) and the benchmarks on emulated detectors read."""

from __future__ import annotations

import numpy as np

from ray3d.body import DETECTOR_JOINT_OFFSETS_M
from ray3d.skeleton import H36M17, Skeleton, layout_skeleton

# Face points detectors measure and the mocap lacks, placed from the upper neck (the mocap's neck/nose joint):
# metres up the neck -> head axis, forward, and to the person's left, for an adult head.
FACE_POINTS = {
    "nose": (0.035, 0.105, 0.0),
    "l_eye": (0.065, 0.085, 0.032), "r_eye": (0.065, 0.085, -0.032),
    "l_ear": (0.03, 0.01, 0.075), "r_ear": (0.03, 0.01, -0.075),
}

def body_frames(positions: np.ndarray) -> np.ndarray:
    """(..., 3, 3) axes of each (..., 17, 3) H36M-17 pose in the world, as columns: x to the person's left
    (from the right hip to the left hip, made horizontal), y forward, z up (a mirror image of a rotation)."""
    across = positions[..., H36M17.index("l_hip"), :] - positions[..., H36M17.index("r_hip"), :]
    across = across * np.array([1.0, 1.0, 0.0])
    across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-9)
    up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), across.shape)
    return np.stack([across, np.cross(across, up), up], -1)


def detector_points(positions: np.ndarray, layout: str | Skeleton = "h36m17") -> np.ndarray:
    """(..., 17, 3) H36M-17 mocap joints -> (..., J, 3) the joints of ``layout`` as a detector defines them:
    joints of the same name as they are, face points (``FACE_POINTS``) from the upper neck, the neck -> head
    axis and the body's forward direction."""
    skeleton = layout_skeleton(layout)
    if skeleton.name == H36M17.name:
        return positions
    unknown = [n for n in skeleton.joint_names if n not in H36M17.joint_names and n not in FACE_POINTS]
    if unknown:
        raise ValueError(f"detector_points: the mocap gives no joint {unknown[0]!r} of layout {skeleton.name}")
    neck = positions[..., H36M17.index("neck_nose"), :]
    up = positions[..., H36M17.index("head"), :] - neck
    up /= np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-9)
    axes = body_frames(positions)
    forward = axes[..., 1] - np.sum(axes[..., 1] * up, -1, keepdims=True) * up
    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)
    left = np.cross(up, forward)
    points = []
    for name in skeleton.joint_names:
        if name in FACE_POINTS:
            along, ahead, side = FACE_POINTS[name]
            points.append(neck + along * up + ahead * forward + side * left)
        else:
            points.append(positions[..., H36M17.index(name), :])
    return np.stack(points, axis=-2)


def offset_joints(points: np.ndarray, axes: np.ndarray, offsets: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(B, F, J, 3) world points of ``skeleton`` moved by (B, J, 3) ``offsets`` given in the body frame (``axes``
    (B, F, 3, 3), see ``body_frames``), mirrored between left and right joints, the same in every frame."""
    offsets = offsets.copy()
    left = list(skeleton.left)
    offsets[:, left] = offsets[:, [skeleton.flip_permutation[i] for i in left]] * np.array([-1.0, 1.0, 1.0])
    offsets[:, [i for i in range(skeleton.num_joints) if i not in skeleton.left + skeleton.right], 0] = 0.0
    return points + np.einsum("bfij,bkj->bfki", axes, offsets)


def detector_offsets(skeleton: Skeleton) -> np.ndarray:
    """(J, 3) ``DETECTOR_JOINT_OFFSETS_M`` for the joints of ``skeleton`` in the body frame (x to the person's left,
    y forward, z up): outward is +x on the left side and -x on the right."""
    offsets = np.zeros((skeleton.num_joints, 3))
    for j, name in enumerate(skeleton.joint_names):
        outward, forward, up = DETECTOR_JOINT_OFFSETS_M.get(name[2:], (0.0, 0.0, 0.0))
        offsets[j] = (outward if j in skeleton.left else -outward, forward, up)
    return offsets


def stand_in_hidden(points: np.ndarray, hidden: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(B, F, J, D) points with each joint ``hidden`` (B, J) put where its nearest unhidden ancestor is (parents
    come first), as ``ray3d.lifting.inputs.stand_in_for_unseen`` places a joint a detector never saw."""
    points = points.copy()
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            points[:, :, joint] = np.where(hidden[:, None, joint, None], points[:, :, parent], points[:, :, joint])
    return points


def hidden_joints(pixels: np.ndarray, sizes: np.ndarray, occluded: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(B, J) joints unseen through a window: those of the (B, J, 2) target-frame ``pixels`` outside the (B, 2)
    image ``sizes``, and, where (B,) ``occluded`` gives an image row (NaN: none), those below it. Hips stay seen."""
    outside = ((pixels < 0) | (pixels > sizes[:, None])).any(-1)
    below = pixels[..., 1] > np.nan_to_num(occluded, nan=np.inf)[:, None]
    hidden = outside | below
    hidden[:, [j for j, name in enumerate(skeleton.joint_names) if name in ("l_hip", "r_hip", "pelvis")]] = False
    return hidden


def occluder_rows(pixels: np.ndarray, rng: np.random.Generator, probability: float, skeleton: Skeleton) -> np.ndarray:
    """(B,) an occluder's top image row for a share ``probability`` of the (B, J, 2) target-frame poses, drawn
    between the hips' row and the lower ankle's; NaN for the rest."""
    hips = pixels[:, [skeleton.index("l_hip"), skeleton.index("r_hip")], 1].max(-1)
    ankles = pixels[:, [skeleton.index("l_ankle"), skeleton.index("r_ankle")], 1].max(-1)
    rows = hips + rng.uniform(0.1, 0.9, len(pixels)) * (ankles - hips)
    return np.where(rng.random(len(pixels)) < probability, rows, np.nan)
