"""Where each H36M-17 joint comes from in each source skeleton: the one table of all mappings.

A source point is a node name of the parsed skeleton (BVH joint origin, ``<joint>.end`` for an End Site, or
an ASF bone's END). Derived joints where a skeleton lacks them (brief section 8, mocap README section 3): pelvis
= mid-hips, spine = mid(pelvis, thorax), and where it has no usable head top, head = nose + (nose - thorax).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.data.skeleton_fk import KinematicTree
from ray3d.errors import InputError
from ray3d.skeleton import H36M17

EXTRAPOLATE_HEAD = "nose + (nose - thorax)"


@dataclasses.dataclass(frozen=True)
class Naming:
    """A source naming convention: H36M joint -> source node (``head`` may be a node or EXTRAPOLATE_HEAD)."""

    name: str
    joints: dict[str, str]
    head_end_site: str | None = None  # used when present with a non-zero offset, else the head is extrapolated
    floor_at_zero: bool = False       # the file's world already has its floor at height 0 (ray3d's own BVH)

    def missing(self, tree: KinematicTree) -> list[str]:
        return [node for node in self.joints.values() if node != EXTRAPOLATE_HEAD and node not in tree.names]


def _sided(left: dict[str, str], right: dict[str, str], common: dict[str, str]) -> dict[str, str]:
    return {**{f"l_{k}": v for k, v in left.items()}, **{f"r_{k}": v for k, v in right.items()}, **common}


def _limbs(hip: str, knee: str, ankle: str, shoulder: str, elbow: str, wrist: str, left: str, right: str):
    parts = dict(hip=hip, knee=knee, ankle=ankle, shoulder=shoulder, elbow=elbow, wrist=wrist)
    return {k: left + v for k, v in parts.items()}, {k: right + v for k, v in parts.items()}


NAMINGS = (
    Naming("asf", _sided(*_limbs("hipjoint", "femur", "tibia", "clavicle", "humerus", "radius", "l", "r"),
                         {"thorax": "lowerneck", "neck_nose": "upperneck", "head": "head"})),
    Naming("cgspeed-motionbuilder",
           _sided(*_limbs("UpLeg", "Leg", "Foot", "Arm", "ForeArm", "Hand", "Left", "Right"),
                  {"thorax": "Neck1", "neck_nose": "Head", "head": EXTRAPOLATE_HEAD}), head_end_site="Head.end"),
    Naming("cgspeed-3dsmax",
           _sided(*_limbs("Hip", "Knee", "Ankle", "Shoulder", "Elbow", "Wrist", "Left", "Right"),
                  {"thorax": "Neck", "neck_nose": "Head", "head": EXTRAPOLATE_HEAD}), head_end_site="Head.end"),
    Naming("cgspeed-daz",
           _sided(*_limbs("Thigh", "Shin", "Foot", "Shldr", "ForeArm", "Hand", "l", "r"),
                  {"thorax": "neck", "neck_nose": "head", "head": EXTRAPOLATE_HEAD})),
    # What ``ray3d lift --out *.bvh`` writes (``ray3d.io.bvh_export``): every H36M-17 joint under its own name.
    Naming("ray3d", {name: name for name in H36M17.joint_names}, floor_at_zero=True),
)


def detect_naming(tree: KinematicTree, source: str) -> Naming:
    """The naming convention whose every joint the skeleton has; an error lists what the closest one lacks."""
    for naming in NAMINGS:
        if not naming.missing(tree):
            return naming
    closest = min(NAMINGS, key=lambda n: len(n.missing(tree)))
    raise InputError(f"{source}: unknown joint names: no supported skeleton naming matches (closest: "
                     f"{closest.name}, which needs {', '.join(closest.missing(tree))}); supported: "
                     f"{', '.join(n.name for n in NAMINGS)}")


def to_h36m17(tree: KinematicTree, positions: np.ndarray, naming: Naming) -> np.ndarray:
    """(F, N, 3) source node positions -> (F, 17, 3) H36M-17 joints (same units and axes)."""
    node = {name: positions[:, i] for i, name in enumerate(tree.names)}
    joint = {h36m: node[src] for h36m, src in naming.joints.items() if src != EXTRAPOLATE_HEAD}
    if naming.head_end_site in tree.names and np.any(tree.offsets[tree.index(naming.head_end_site)] != 0):
        joint["head"] = node[naming.head_end_site]
    elif naming.joints["head"] == EXTRAPOLATE_HEAD:
        joint["head"] = 2 * joint["neck_nose"] - joint["thorax"]
    joint.setdefault("pelvis", (joint["l_hip"] + joint["r_hip"]) / 2)
    joint.setdefault("spine", (joint["pelvis"] + joint["thorax"]) / 2)
    return np.stack([joint[name] for name in H36M17.joint_names], axis=1)


def foot_nodes(tree: KinematicTree, naming: Naming) -> list[int]:
    """The ankle nodes and everything below them (toes, toe tips): the points that touch the floor."""
    ankles = [tree.index(naming.joints[f"{side}_ankle"]) for side in "lr"]
    return sorted({i for a in ankles for i in tree.descendants(a)})
