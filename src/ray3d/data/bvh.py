"""BVH reader: hierarchy, channels and motion, with errors that name the file, line and problem."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ray3d.data.skeleton_fk import KinematicTree
from ray3d.errors import InputError

_ROTATION_CHANNELS = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
_POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")


@dataclasses.dataclass
class BvhMotion:
    """A parsed BVH file. ``channels[i]`` lists node i's channel names; ``motion`` is (F, total channels)."""

    path: Path
    tree: KinematicTree
    channels: list[list[str]]
    motion: np.ndarray
    frame_time: float

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def positions(self) -> np.ndarray:
        """(F, N, 3) world positions of every node (joint origins and end sites) in file units and axes."""
        frames, count = len(self.motion), len(self.tree.names)
        rotations = np.broadcast_to(np.eye(3), (frames, count, 3, 3)).copy()
        translations = np.broadcast_to(self.tree.offsets, (frames, count, 3)).copy()
        column = 0
        for i, names in enumerate(self.channels):
            values = self.motion[:, column:column + len(names)]
            column += len(names)
            position = [values[:, k] for k, n in enumerate(names) if n in _POSITION_CHANNELS]
            if position:
                # Position channels give the node's translation outright (the root's path).
                order = [n for n in names if n in _POSITION_CHANNELS]
                translations[:, i] = np.stack([position[order.index(axis)] for axis in _POSITION_CHANNELS], -1)
            axes = "".join(_ROTATION_CHANNELS[n] for n in names if n in _ROTATION_CHANNELS)
            if axes:
                angles = np.stack([values[:, k] for k, n in enumerate(names) if n in _ROTATION_CHANNELS], -1)
                # Rotations multiply in the listed order: intrinsic Euler angles in scipy's terms.
                rotations[:, i] = Rotation.from_euler(axes, angles, degrees=True).as_matrix()
        return self.tree.forward_kinematics(rotations, translations)


def read_bvh(path: str | Path) -> BvhMotion:
    """Parse a BVH file.

    Raises:
        InputError: naming the file and line for a malformed hierarchy, an unknown channel, a channel count
            that does not match the motion rows, or a truncated motion section.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None
    lines = text.splitlines()
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[list[str]] = []
    stack: list[int] = []
    pending: int | None = None  # node whose '{' is expected next
    line_no = 0

    def fail(message: str) -> InputError:
        return InputError(f"{path}: line {line_no}: {message}")

    if not lines or lines[0].strip() != "HIERARCHY":
        raise InputError(f"{path}: not a BVH file (the first line must be HIERARCHY)")
    for line_no, raw in enumerate(lines[1:], start=2):
        tokens = raw.split()
        if not tokens:
            continue
        keyword = tokens[0]
        if keyword in ("ROOT", "JOINT", "End"):
            if keyword == "ROOT" and (names or stack):
                raise fail("a second ROOT; only one skeleton per file is supported")
            if keyword != "ROOT" and not stack:
                raise fail(f"{keyword} outside any ROOT")
            name = f"{names[stack[-1]]}.end" if keyword == "End" else " ".join(tokens[1:])
            if not name:
                raise fail("joint without a name")
            if name in names:
                raise fail(f"duplicate joint name {name!r}")
            names.append(name)
            parents.append(stack[-1] if stack else -1)
            offsets.append([0.0, 0.0, 0.0])
            channels.append([])
            pending = len(names) - 1
        elif keyword == "{":
            if pending is None:
                raise fail("'{' without a joint")
            stack.append(pending)
            pending = None
        elif keyword == "}":
            if not stack:
                raise fail("unbalanced '}'")
            stack.pop()
        elif keyword == "OFFSET":
            try:
                offsets[stack[-1]] = [float(v) for v in tokens[1:4]]
            except (ValueError, IndexError):
                raise fail(f"OFFSET needs three numbers, got {raw.strip()!r}") from None
            if len(tokens) != 4:
                raise fail(f"OFFSET needs three numbers, got {raw.strip()!r}")
        elif keyword == "CHANNELS":
            if not stack or names[stack[-1]].endswith(".end"):
                raise fail("CHANNELS outside a joint")
            try:
                count = int(tokens[1])
            except (ValueError, IndexError):
                raise fail(f"CHANNELS needs a count, got {raw.strip()!r}") from None
            listed = tokens[2:]
            if len(listed) != count:
                raise fail(f"CHANNELS says {count} channels but lists {len(listed)}")
            unknown = [c for c in listed if c not in _ROTATION_CHANNELS and c not in _POSITION_CHANNELS]
            if unknown:
                raise fail(f"unknown channel(s) {', '.join(unknown)}")
            channels[stack[-1]] = listed
        elif keyword == "MOTION":
            if stack:
                raise fail("MOTION before the hierarchy is closed (missing '}')")
            break
        else:
            raise fail(f"unexpected {keyword!r} in the hierarchy")
    else:
        raise InputError(f"{path}: truncated: no MOTION section")
    if not names:
        raise InputError(f"{path}: no joints in the hierarchy")

    header = lines[line_no:line_no + 2]
    try:
        frames = int(header[0].split(":")[1])
        frame_time = float(header[1].split(":")[1])
    except (IndexError, ValueError):
        raise InputError(f"{path}: line {line_no + 1}: expected 'Frames: N' and 'Frame Time: T'") from None
    if frame_time <= 0:
        raise InputError(f"{path}: line {line_no + 2}: frame time must be positive, got {frame_time}")
    rows = [row for row in lines[line_no + 2:] if row.strip()]
    total = sum(len(c) for c in channels)
    if len(rows) < frames:
        raise InputError(f"{path}: truncated: the header announces {frames} frames but only {len(rows)} follow")
    try:
        motion = np.array([[float(v) for v in row.split()] for row in rows[:frames]])
    except ValueError:
        raise InputError(f"{path}: motion section: rows must hold numbers only, and each the same count "
                         f"({total} channels)") from None
    if motion.ndim != 2 or motion.shape[1] != total:
        counts = sorted({len(row.split()) for row in rows[:frames]})
        raise InputError(f"{path}: motion rows hold {counts} values but the hierarchy declares {total} channels")
    if not np.isfinite(motion).all():
        raise InputError(f"{path}: motion section contains NaN or infinite values")
    return BvhMotion(path, KinematicTree(names, parents, np.array(offsets)), channels, motion, frame_time)
