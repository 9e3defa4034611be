"""Joint layouts, converters between them, and the left/right flip.

Everything structural is derived from joint NAMES: a side prefix ``l_`` / ``r_`` gives left/right and the
flip permutation; the limb words give the five RIE groups (torso, two arms, two legs). Converters are linear
maps (a (J_target, J_source) weight matrix) so they apply to 2D pixels, 3D points, numpy and torch alike.
"""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.arrays import Array, like, namespace, stack_last

ARM_PARTS = ("shoulder", "elbow", "wrist")
LEG_PARTS = ("hip", "knee", "ankle")
GROUP_NAMES = ("torso", "left_arm", "right_arm", "left_leg", "right_leg")


def _side(name: str) -> str | None:
    return {"l_": "left", "r_": "right"}.get(name[:2])


@dataclasses.dataclass(frozen=True)
class Skeleton:
    """A joint layout: ordered joint names and each joint's parent index (-1 for the root)."""

    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]

    def __post_init__(self) -> None:
        assert len(self.joint_names) == len(self.parents), self.name
        assert len(set(self.joint_names)) == len(self.joint_names), self.name

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    def index(self, joint: str) -> int:
        try:
            return self.joint_names.index(joint)
        except ValueError:
            raise InputError(f"layout {self.name}: no joint named {joint!r}") from None

    @functools.cached_property
    def left(self) -> tuple[int, ...]:
        return tuple(i for i, n in enumerate(self.joint_names) if _side(n) == "left")

    @functools.cached_property
    def right(self) -> tuple[int, ...]:
        return tuple(i for i, n in enumerate(self.joint_names) if _side(n) == "right")

    @functools.cached_property
    def flip_permutation(self) -> tuple[int, ...]:
        """Index of each joint's mirror image (itself for central joints)."""
        swap = {"l_": "r_", "r_": "l_"}
        return tuple(self.index(swap[n[:2]] + n[2:]) if _side(n) else i for i, n in enumerate(self.joint_names))

    @functools.cached_property
    def groups(self) -> dict[str, tuple[int, ...]]:
        """The five RIE joint groups by name; hips belong to the legs, shoulders to the arms."""
        groups: dict[str, list[int]] = {g: [] for g in GROUP_NAMES}
        for i, n in enumerate(self.joint_names):
            side, part = _side(n), n[2:]
            limb = "arm" if side and part in ARM_PARTS else "leg" if side and part in LEG_PARTS else None
            groups[f"{side}_{limb}" if limb else "torso"].append(i)
        return {g: tuple(v) for g, v in groups.items()}


def _subset(source: Skeleton, name: str, keep: list[str]) -> Skeleton:
    """A layout of some of ``source``'s joints; each keeps its nearest kept ancestor as parent."""
    kept = [source.index(n) for n in keep]
    parents = []
    for i in kept:
        p = source.parents[i]
        while p != -1 and p not in kept:
            p = source.parents[p]
        parents.append(kept.index(p) if p != -1 else -1)
    return Skeleton(name, tuple(keep), tuple(parents))


H36M17 = Skeleton(
    "h36m17",
    ("pelvis", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle", "spine", "thorax", "neck_nose", "head",
     "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist"),
    (-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15),
)
# The cross-dataset layout: H36M-17 without spine, thorax and neck.
H36M14 = _subset(H36M17, "h36m14", [n for n in H36M17.joint_names if n not in ("spine", "thorax", "neck_nose")])
HUMANEVA15 = Skeleton(
    "humaneva15",
    ("pelvis", "thorax", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist",
     "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle", "head"),
    (-1, 0, 1, 2, 3, 1, 5, 6, 0, 8, 9, 0, 11, 12, 1),
)
# MPI-INF-3DHP's 17-joint test layout, in Human3.6M order; its neck and head top differ in name only.
MPI_INF_3DHP17 = Skeleton(
    "3dhp17",
    tuple({"neck_nose": "neck", "head": "head_top"}.get(n, n) for n in H36M17.joint_names),
    H36M17.parents,
)
COCO17 = Skeleton(
    "coco17",
    ("nose", "l_eye", "r_eye", "l_ear", "r_ear", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist",
     "r_wrist", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"),
    (-1, 0, 0, 1, 2, 0, 0, 5, 6, 7, 8, 5, 6, 11, 12, 13, 14),
)
BLAZEPOSE33 = Skeleton(
    "blazepose33",
    ("nose", "l_eye_inner", "l_eye", "l_eye_outer", "r_eye_inner", "r_eye", "r_eye_outer", "l_ear", "r_ear",
     "l_mouth", "r_mouth", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_pinky",
     "r_pinky", "l_index", "r_index", "l_thumb", "r_thumb", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle",
     "r_ankle", "l_heel", "r_heel", "l_foot_index", "r_foot_index"),
    (-1, 0, 1, 2, 0, 4, 5, 3, 6, 0, 0, 0, 0, 11, 12, 13, 14, 15, 16, 15, 16, 15, 16, 11, 12, 23, 24, 25, 26,
     27, 28, 27, 28),
)
# OpenPose BODY_25: its "neck" sits between the shoulders, "mid_hip" between the hips.
BODY25 = Skeleton(
    "body25",
    ("nose", "neck", "r_shoulder", "r_elbow", "r_wrist", "l_shoulder", "l_elbow", "l_wrist", "mid_hip", "r_hip",
     "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle", "r_eye", "l_eye", "r_ear", "l_ear", "l_big_toe",
     "l_small_toe", "l_heel", "r_big_toe", "r_small_toe", "r_heel"),
    (1, 8, 1, 2, 3, 1, 5, 6, -1, 8, 9, 10, 8, 12, 13, 0, 0, 15, 16, 14, 19, 14, 11, 22, 11),
)
# AlphaPose's Halpe-26 (also mmpose's halpe26 models): COCO-17, then head top, neck, mid-hip and six foot points.
HALPE26 = Skeleton(
    "halpe26",
    COCO17.joint_names + ("head_top", "neck", "mid_hip", "l_big_toe", "r_big_toe", "l_small_toe", "r_small_toe",
                          "l_heel", "r_heel"),
    (18, 0, 0, 1, 2, 18, 18, 5, 6, 7, 8, 19, 19, 11, 12, 13, 14, 18, 19, -1, 15, 16, 15, 16, 15, 16),
)
# The input of detector-native models: the joints every detector layout above measures (COCO-17's) and the
# pelvis, the mid-hips, first: the root that ray models need. The mocap's pelvis is the mid-hips too, so nothing
# in it is synthesised. Parents come before their children (a missed joint collapses onto its parent).
DETECTOR18 = Skeleton(
    "detector18",
    ("pelvis", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_shoulder", "r_shoulder", "l_elbow",
     "r_elbow", "l_wrist", "r_wrist", "nose", "l_eye", "r_eye", "l_ear", "r_ear"),
    (-1, 0, 0, 1, 2, 3, 4, 1, 2, 7, 8, 9, 10, 0, 13, 13, 14, 15),
)
LAYOUTS = {s.name: s for s in (H36M17, H36M14, HUMANEVA15, MPI_INF_3DHP17, COCO17, HALPE26, BLAZEPOSE33, BODY25,
                               DETECTOR18)}
# Layouts that detectors produce, which convert to the detector-native models' input by name alone.
DETECTOR_LAYOUTS = ("coco17", "halpe26", "blazepose33", "body25")

# How far the head top lies beyond the mid-ears, as a fraction of the thorax -> mid-ears vector.
HEAD_TOP_EXTENSION = 0.5
_HALF = 0.5
_FACE_TO_H36M: dict[str, dict[str, float]] = {
    "pelvis": {"l_hip": _HALF, "r_hip": _HALF},
    "thorax": {"l_shoulder": _HALF, "r_shoulder": _HALF},
    "spine": {"l_hip": _HALF / 2, "r_hip": _HALF / 2, "l_shoulder": _HALF / 2, "r_shoulder": _HALF / 2},
    "neck_nose": {"nose": 1.0},
    "head": {"l_ear": _HALF * (1 + HEAD_TOP_EXTENSION), "r_ear": _HALF * (1 + HEAD_TOP_EXTENSION),
             "l_shoulder": -_HALF * HEAD_TOP_EXTENSION, "r_shoulder": -_HALF * HEAD_TOP_EXTENSION},
}
# Joints of a target layout not found by name in the source: (source, target) -> {target joint: {source joint: w}}.
_RECIPES: dict[tuple[str, str], dict[str, dict[str, float]]] = {
    ("coco17", "h36m17"): _FACE_TO_H36M,
    # Halpe's own head top is not used: every detector layout derives the head from the ears alike, as trained.
    ("halpe26", "h36m17"): _FACE_TO_H36M,
    ("blazepose33", "h36m17"): _FACE_TO_H36M,
    ("body25", "h36m17"): _FACE_TO_H36M,
    ("3dhp17", "h36m17"): {"neck_nose": {"neck": 1.0}, "head": {"head_top": 1.0}},
    **{(layout, "detector18"): {"pelvis": _FACE_TO_H36M["pelvis"]} for layout in DETECTOR_LAYOUTS},
}


def layout_skeleton(layout: str | Skeleton) -> Skeleton:
    """The skeleton of a joint layout given by name (``h36m17``, ``coco17``, ...) or as a ``Skeleton``."""
    if isinstance(layout, Skeleton):
        return layout
    if layout not in LAYOUTS:
        raise InputError(f"unknown joint layout {layout!r}; known: {', '.join(LAYOUTS)} (for an unknown layout, "
                         "convert the keypoints to one of these)")
    return LAYOUTS[layout]


def layout_named_by(joint_names) -> Skeleton | None:
    """The layout whose joints are ``joint_names``, in that order; None if no layout has them."""
    return next((s for s in LAYOUTS.values() if s.joint_names == tuple(joint_names)), None)


def _missing_joints(src: Skeleton, dst: Skeleton) -> list[str]:
    recipe = _RECIPES.get((src.name, dst.name), {})
    return [joint for joint in dst.joint_names if joint not in recipe and joint not in src.joint_names]


@functools.cache
def conversion_matrix(source: str, target: str) -> np.ndarray:
    """(J_target, J_source) weights taking ``source`` joints to ``target`` joints (rows sum to 1).

    Joints are matched by name; a target joint missing from the source comes from a recipe of derived joints
    (brief section 8). Raises ``InputError`` when the source lacks what the target needs.
    """
    src, dst = layout_skeleton(source), layout_skeleton(target)
    missing = _missing_joints(src, dst)
    if missing:
        reachable = [name for name, layout in LAYOUTS.items() if not _missing_joints(src, layout)]
        raise InputError(f"cannot convert {src.name} to {dst.name}: {src.name} has no joint {missing[0]!r}; "
                         f"it converts to: {', '.join(reachable)}")
    recipe = _RECIPES.get((src.name, dst.name), {})
    matrix = np.zeros((dst.num_joints, src.num_joints))
    for k, joint in enumerate(dst.joint_names):
        for joint_name, weight in recipe.get(joint, {joint: 1.0}).items():
            matrix[k, src.index(joint_name)] = weight
    matrix.setflags(write=False)
    return matrix


def _check_joint_axis(array: Array, skeleton: Skeleton, axis: int, what: str) -> None:
    if array.shape[axis] != skeleton.num_joints:
        raise InputError(f"layout {skeleton.name}: expected {skeleton.num_joints} {what}, got shape "
                         f"{tuple(array.shape)}")


def convert(points: Array, source: str | Skeleton, target: str | Skeleton = "h36m17") -> Array:
    """Convert (..., J_source, D) joints (pixels or 3D, numpy or torch) to the ``target`` layout."""
    src, dst = layout_skeleton(source), layout_skeleton(target)
    _check_joint_axis(points, src, -2, "joints on axis -2")
    weights = conversion_matrix(src.name, dst.name)
    return namespace(points).einsum("kj,...jd->...kd", like(weights, points), points)


def convert_confidences(confidences: Array, source: str | Skeleton, target: str | Skeleton = "h36m17") -> Array:
    """(..., J_source) confidences -> (..., J_target): a derived joint is as sure as its least sure source."""
    src, dst = layout_skeleton(source), layout_skeleton(target)
    _check_joint_axis(confidences, src, -1, "confidences on the last axis")
    xp = namespace(confidences)
    used = like(conversion_matrix(src.name, dst.name) != 0, confidences) > 0
    inf = like(np.inf, confidences)
    return xp.amin(xp.where(used, confidences[..., None, :], inf), -1)


def convert_keypoints(keypoints: np.ndarray, source: str | Skeleton, confidences: np.ndarray | None = None,
                      target: str | Skeleton = "h36m17") -> tuple[np.ndarray, np.ndarray]:
    """A detector's (..., J_source, 2) pixels (NaN where missing; optional (..., J_source) confidences, 0 =
    missing) -> (..., J_target, 2) pixels of ``target`` (H36M-17 unless told), NaN where missing, and
    (..., J_target) whether each joint was seen. A derived joint (e.g. the pelvis from two hips) is missing when
    any of its sources is."""
    seen = np.isfinite(keypoints).all(-1)
    if confidences is not None:
        seen &= np.asarray(confidences) > 0
    found = convert_confidences(seen.astype(np.float64), source, target) > 0
    pixels = convert(np.where(seen[..., None], keypoints, 0.0), source, target)
    return np.where(found[..., None], pixels, np.nan), found


def flip(points: Array, layout: str | Skeleton = "h36m17") -> Array:
    """Mirror (..., J, D) joints: negate the first coordinate and swap left and right joints."""
    skeleton = layout_skeleton(layout)
    if points.shape[-2] != skeleton.num_joints:
        raise InputError(f"flip: layout {skeleton.name} has {skeleton.num_joints} joints, got shape "
                         f"{tuple(points.shape)}")
    mirrored = points[..., list(skeleton.flip_permutation), :]
    sign = like(np.array([-1.0] + [1.0] * (points.shape[-1] - 1)), points)
    return mirrored * sign


def mirror_pixels(pixels: Array, cx: Array, layout: str | Skeleton = "h36m17") -> Array:
    """Mirror (..., J, 2) pixels about the image column ``cx`` (broadcast against (...)), swapping left and
    right joints: the image of the mirrored scene, as :func:`flip` mirrors the scene itself."""
    mirrored = flip(pixels, layout)
    return stack_last([mirrored[..., 0] + 2 * cx, mirrored[..., 1]])


# COCO-17 starts with five face points close together; H36M-17 (and 3DHP-17, the same order) with the pelvis
# and a leg, spread over half the body. As a fraction of the person's extent in the image:
FACE_SPREAD_MAX = 0.2
LEG_SPREAD_MIN = 0.3


def identify_17_joint_layout(pixels: np.ndarray) -> str | None:
    """``"coco17"`` or ``"h36m17"`` from the geometry of (N, 17, 2) keypoints (NaN where missing), or None when
    they fit neither: the spread of the first five joints over the person's size, median over detections."""
    pixels = np.asarray(pixels, dtype=np.float64)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN detections
        extent = np.nanmax(np.nanmax(pixels, axis=1) - np.nanmin(pixels, axis=1), axis=-1)
        first = pixels[:, :5]
        pairwise = np.linalg.norm(first[:, :, None] - first[:, None], axis=-1)
        spread = np.nanmedian(np.nanmax(pairwise, axis=(1, 2)) / np.where(extent > 0, extent, np.nan))
    if not np.isfinite(spread):
        return None
    if spread < FACE_SPREAD_MAX:
        return "coco17"
    return "h36m17" if spread > LEG_SPREAD_MIN else None
