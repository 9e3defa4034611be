"""A lifted track as BVH motion (Blender, Maya, MotionBuilder): a skeleton whose rest offsets are the track's
median bone lengths, per-frame joint rotations, and the root's path in metres.

The file is Y up (world (x, y, z) -> BVH (x, z, -y)), as BVH importers expect by default. In the rest pose the
person faces +Z with their left along +X: legs straight down, arms out sideways (a T-pose), and the hips,
spine and shoulders as the track's median body holds them. Each joint's rotation turns its rest bones onto the
lifted ones (the best fit of all its bones where it has several, the smallest turn where it has one).

A network's bone lengths vary from frame to frame (on the demo clip by several centimetres), which a skeleton of
fixed bones cannot follow. So by default every joint also carries position channels, its offset from its parent
in the parent's frame (the rest direction, at that frame's length): the file reproduces the lifted joints
exactly, and a tool that ignores those channels still sees the rigid skeleton move. ``rigid=True`` writes
rotations only (for retargeting): its joints differ from the lifted ones by the bone-length variation."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ray3d.errors import InputError
from ray3d.io.atomic import atomic_path, refuse_existing
from ray3d.skeleton import Skeleton, layout_named_by

# World (z up) -> BVH (y up): a rotation of -90 degrees about x, (x, y, z) -> (x, z, -y). OpenSim's TRC uses the same.
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
EULER_ORDER = "ZXY"  # the channel order of the CMU BVH files; intrinsic, as BVH multiplies them
END_SITE_LENGTH = 0.1  # metres: the stub that closes each chain (hands, feet, head), along its last bone
_LIMB_DIRECTIONS = {"knee": (0, -1, 0), "ankle": (0, -1, 0), "elbow": (1, 0, 0), "wrist": (1, 0, 0)}


def _children(skeleton: Skeleton) -> list[list[int]]:
    return [[c for c, p in enumerate(skeleton.parents) if p == j] for j in range(skeleton.num_joints)]


def _body_frames(vectors: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(T, 3, 3) the rotation per frame that best turns the ``rest`` bones (C, 3) onto ``vectors`` (T, C, 3),
    by least squares (Kabsch)."""
    u, _, vt = np.linalg.svd(np.einsum("tci,cj->tij", vectors, rest))
    flip = np.sign(np.linalg.det(u @ vt))
    return u @ (np.eye(3) * np.stack([np.ones_like(flip), np.ones_like(flip), flip], -1)[:, None]) @ vt


def _smallest_turns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T, 3, 3) the smallest rotation taking direction a (T, 3) onto b (T, 3)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis, axis=-1), np.sum(a * b, axis=-1)
    # Opposite directions: any axis perpendicular to a serves.
    fallback = np.cross(a, np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    axis = np.where(sine[:, None] > 1e-9, axis, fallback)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    return Rotation.from_rotvec(axis * np.arctan2(sine, cosine)[:, None]).as_matrix()


def rest_offsets(joints: np.ndarray, skeleton: Skeleton, children: list[list[int]]) -> np.ndarray:
    """(J, 3) each joint's offset from its parent in the rest pose, BVH axes, metres, from (T, J, 3) Y-up
    joints: the median bone length along the limb's rest direction for arms and legs; the median of the body
    (bones expressed in the parent's own frame) for a joint whose parent has several children."""
    offsets = np.zeros((skeleton.num_joints, 3))
    for parent, kids in enumerate(children):
        if not kids:
            continue
        bones = joints[:, kids] - joints[:, [parent]]  # (T, C, 3)
        lengths = np.median(np.linalg.norm(bones, axis=-1), axis=0)
        if len(kids) == 1 and skeleton.joint_names[kids[0]][2:] in _LIMB_DIRECTIONS:
            name = skeleton.joint_names[kids[0]]
            direction = np.array(_LIMB_DIRECTIONS[name[2:]], dtype=float)
            if name.startswith("r_"):
                direction[0] *= -1
            offsets[kids[0]] = lengths[0] * direction
        elif len(kids) == 1:  # the spine and head: straight up
            offsets[kids[0]] = (0.0, lengths[0], 0.0)
        else:  # the body around the joint as the track holds it, in a frame of left (+x) and up (+y)
            frames = _local_frames(joints, skeleton, parent, kids)
            local = np.einsum("tji,tcj->tci", frames, bones)
            directions = np.median(local / np.linalg.norm(local, axis=-1, keepdims=True), axis=0)
            offsets[kids] = lengths[:, None] * directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    return offsets


def _local_frames(joints: np.ndarray, skeleton: Skeleton, joint: int, kids: list[int]) -> np.ndarray:
    """(T, 3, 3) columns left, up, forward at a joint with several children: left from its right child to its
    left one, up along its central child (orthogonalised)."""
    names = [skeleton.joint_names[k] for k in kids]
    left = [k for k, n in zip(kids, names) if n.startswith("l_")]
    right = [k for k, n in zip(kids, names) if n.startswith("r_")]
    central = [k for k, n in zip(kids, names) if not n.startswith(("l_", "r_"))]
    if not (left and right and central):
        raise InputError(f"layout {skeleton.name}: joint {skeleton.joint_names[joint]} needs a left, a right and a "
                         "central child to export BVH")
    x = joints[:, left[0]] - joints[:, right[0]]
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    up = joints[:, central[0]] - joints[:, joint]
    y = up - np.sum(up * x, axis=-1, keepdims=True) * x
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def joint_rotations(joints: np.ndarray, skeleton: Skeleton, offsets: np.ndarray,
                    children: list[list[int]]) -> np.ndarray:
    """(T, J, 3, 3) global rotations turning the rest bones (``offsets``) onto the lifted ones; a joint with no
    child keeps its parent's."""
    rotations = np.zeros((len(joints), skeleton.num_joints, 3, 3))
    for joint in range(skeleton.num_joints):  # parents come before children in every layout
        parent = skeleton.parents[joint]
        inherited = np.broadcast_to(np.eye(3), rotations[:, 0].shape) if parent < 0 else rotations[:, parent]
        kids = children[joint]
        if len(kids) > 1:
            rotations[:, joint] = _body_frames(joints[:, kids] - joints[:, [joint]], offsets[kids])
        elif kids:
            rest = np.einsum("tij,j->ti", inherited, offsets[kids[0]])
            rotations[:, joint] = _smallest_turns(rest, joints[:, kids[0]] - joints[:, joint]) @ inherited
        else:
            rotations[:, joint] = inherited
    return rotations


def bvh_text(joints: np.ndarray, skeleton: Skeleton, fps: float, rigid: bool = False) -> str:
    """The BVH file of one person's (T, J, 3) world joints (metres, z up) in ``skeleton``'s layout at ``fps``;
    ``rigid``: rotations only (fixed bone lengths) instead of each joint's offset too."""
    if len(joints) == 0 or not np.isfinite(joints).all():
        raise InputError("BVH export: the track needs at least one frame and finite joints")
    if list(skeleton.parents).count(-1) != 1 or any(p >= j for j, p in enumerate(skeleton.parents) if p >= 0):
        raise InputError(f"layout {skeleton.name}: BVH export needs one root and parents before children")
    y_up = joints @ Y_UP.T
    children = _children(skeleton)
    offsets = rest_offsets(y_up, skeleton, children)
    rotations = joint_rotations(y_up, skeleton, offsets, children)
    lines = ["HIERARCHY"]
    order = []  # joints in the order their channels appear: depth first, as written

    def node(joint: int, depth: int) -> None:
        order.append(joint)
        pad = "  " * depth
        is_root = skeleton.parents[joint] < 0
        lines.append(f"{pad}{'ROOT' if is_root else 'JOINT'} {skeleton.joint_names[joint]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.6f}' for v in offsets[joint])}")
        rotation_channels = " ".join(f"{axis}rotation" for axis in EULER_ORDER)
        lines.append(f"{pad}  CHANNELS 3 {rotation_channels}" if rigid and not is_root
                     else f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rotation_channels}")
        for kid in children[joint]:
            node(kid, depth + 1)
        if not children[joint]:
            stub = offsets[joint] / max(np.linalg.norm(offsets[joint]), 1e-9) * END_SITE_LENGTH
            lines.extend([f"{pad}  End Site", f"{pad}  {{",
                          f"{pad}    OFFSET {' '.join(f'{v:.6f}' for v in stub)}", f"{pad}  }}"])
        lines.append(pad + "}")

    node(skeleton.parents.index(-1), 0)
    local = rotations.copy()
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            local[:, joint] = np.swapaxes(rotations[:, parent], -1, -2) @ rotations[:, joint]
    angles = Rotation.from_matrix(local[:, order].reshape(-1, 3, 3)).as_euler(EULER_ORDER, degrees=True)
    angles = angles.reshape(len(joints), len(order), 3)
    positions = y_up.copy()  # the root's path; every other joint's offset in its parent's frame
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            positions[:, joint] = np.einsum("tji,tj->ti", rotations[:, parent], y_up[:, joint] - y_up[:, parent])
    positions = positions[:, order]
    channels = [np.concatenate([positions[:, k], angles[:, k]], axis=1) if k == 0 or not rigid else angles[:, k]
                for k in range(len(order))]
    motion = np.concatenate(channels, axis=1)
    lines += ["MOTION", f"Frames: {len(joints)}", f"Frame Time: {1.0 / fps:.10f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in motion]
    return "\n".join(lines) + "\n"


def export_paths(path: str | Path, world) -> dict[str, Path]:
    """{track: file} that ``write_world`` writes for ``path`` and ``world`` (a ``ray3d.io.world.World``): one file
    for every track, except BVH, which holds one skeleton: ``NAME_TRACK.bvh`` for each track when there are
    several."""
    path = Path(path)
    if path.suffix.lower() != ".bvh" or len(world.tracks) == 1:
        return {track: path for track in world.tracks}
    # A track id becomes part of a file name: anything but letters, digits, dot, dash and underscore is replaced.
    safe = {track: re.sub(r"[^A-Za-z0-9._-]", "_", track) for track in world.tracks}
    if len(set(safe.values())) < len(safe):
        safe = {track: f"{i}_{name}" for i, (track, name) in enumerate(safe.items())}
    return {track: path.with_name(f"{path.stem}_{safe[track]}{path.suffix}") for track in world.tracks}


def write_bvh_files(path: Path, world, overwrite: bool) -> Path:
    """Each track of ``world`` (a ``World``) as its BVH file (``export_paths``); consecutive frames only."""
    targets = export_paths(path, world)
    for track, target in targets.items():
        refuse_existing(target, overwrite)
        if np.any(np.diff(world.tracks[track].frames) != 1):
            raise InputError(f"track {track}: its frames are not consecutive; BVH holds evenly spaced frames only")
    skeleton = layout_named_by(world.joint_names)
    if skeleton is None:
        raise InputError(f"world: joints {', '.join(world.joint_names[:4])}, ... match no known layout")
    for track, target in targets.items():
        text = bvh_text(world.tracks[track].joints, skeleton, world.fps)
        with atomic_path(target, overwrite) as temporary:
            temporary.write_text(text)
    return path


def trc_text(world, name: str) -> str:
    """The TRC file (OpenSim's "PathFileType 4" marker format, tab-separated) of every track: one row per frame
    of any track, blank where a track has no frame."""
    several = len(world.tracks) > 1
    markers = [f"{t}_{j}" if several else j for t in world.tracks for j in world.joint_names]
    frames = np.unique(np.concatenate([r.frames for r in world.tracks.values()]))
    table = np.full((len(frames), len(markers), 3), np.nan)
    for k, result in enumerate(world.tracks.values()):
        rows = np.searchsorted(frames, result.frames)
        table[rows, 17 * k:17 * (k + 1)] = 1000.0 * result.joints @ Y_UP.T
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{world.fps:g}\t{world.fps:g}\t{len(frames)}\t{len(markers)}\tmm\t{world.fps:g}\t1\t{len(frames)}",
             "Frame#\tTime\t" + "\t".join(f"{m}\t\t" for m in markers).rstrip("\t"),
             "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, len(markers) + 1)), ""]
    for row, (frame, values) in enumerate(zip(frames, table)):
        cells = ["" if not np.isfinite(v) else f"{v:.2f}" for v in values.ravel()]
        lines.append(f"{row + 1}\t{frame / world.fps:.5f}\t" + "\t".join(cells))
    return "\n".join(lines) + "\n"
