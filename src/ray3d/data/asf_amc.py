"""Acclaim ASF (skeleton) / AMC (motion) reader and forward kinematics.

Conventions (Acclaim, as the CMU and HDM05 files use them): a bone's local rotation is ``L = C M C^T`` with C
from its ``axis`` line and M from its AMC dofs, each composed about fixed axes in the listed order
(``rx ry rz`` -> Rz Ry Rx); ``W_child = W_parent L``; a bone ends at its start plus ``W (direction * length)``.
Each bone's node is its END point.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ray3d.data.skeleton_fk import KinematicTree
from ray3d.errors import InputError

INCH_M = 0.0254


@dataclasses.dataclass
class AsfBone:
    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray  # (3, 3) C
    dofs: list[str]


@dataclasses.dataclass
class AsfSkeleton:
    path: Path
    length_unit: float  # file length units per inch (the ':units length' value is its inverse)
    degrees: bool
    root_order: list[str]
    root_axis: np.ndarray
    root_position: np.ndarray
    bones: dict[str, AsfBone]
    children: dict[str, list[str]]

    @property
    def metres_per_unit(self) -> float:
        """CMU's 'length 0.45' means file units are 1/0.45 inch."""
        return INCH_M / self.length_unit


def _read_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="latin-1").splitlines()  # HDM05 files are Latin-1 with CRLF
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None


def _euler(order: str, angles: np.ndarray, degrees: bool) -> np.ndarray:
    """Rotation matrices about fixed axes applied in the listed order (extrinsic)."""
    return Rotation.from_euler(order.lower(), angles, degrees=degrees).as_matrix()


def read_asf(path: str | Path) -> AsfSkeleton:
    path = Path(path)
    lines = [line.split("#")[0].strip() for line in _read_lines(path)]
    section = None
    length_unit, degrees = 1.0, True
    root_order: list[str] = []
    root_axis_order, root_orientation, root_position = "XYZ", np.zeros(3), np.zeros(3)
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
    block: dict[str, list[str]] | None = None

    def fail(line_no: int, message: str) -> InputError:
        return InputError(f"{path}: line {line_no}: {message}")

    def numbers(line_no: int, values: list[str], count: int, what: str) -> np.ndarray:
        try:
            result = np.array([float(v) for v in values[:count]])
        except ValueError:
            raise fail(line_no, f"{what}: expected {count} numbers, got {' '.join(values)!r}") from None
        if len(result) != count:
            raise fail(line_no, f"{what}: expected {count} numbers, got {' '.join(values)!r}")
        return result

    for line_no, line in enumerate(lines, start=1):
        if not line:
            continue
        if line.startswith(":"):
            section = line.split()[0][1:]
            continue
        tokens = line.split()
        if section == "units":
            if tokens[0] == "length":
                length_unit = float(numbers(line_no, tokens[1:], 1, "length")[0])
            elif tokens[0] == "angle":
                degrees = tokens[1].lower().startswith("deg")
        elif section == "root":
            if tokens[0] == "order":
                root_order = [t.upper() for t in tokens[1:]]
            elif tokens[0] == "axis":
                root_axis_order = tokens[1].upper()
            elif tokens[0] == "position":
                root_position = numbers(line_no, tokens[1:], 3, "root position")
            elif tokens[0] == "orientation":
                root_orientation = numbers(line_no, tokens[1:], 3, "root orientation")
        elif section == "bonedata":
            if tokens[0] == "begin":
                block = {}
            elif tokens[0] == "end":
                if block is None or "name" not in block:
                    raise fail(line_no, "bone block without a name")
                name = block["name"][0]
                axis = block.get("axis", ["0", "0", "0", "XYZ"])
                bones[name] = AsfBone(
                    name=name,
                    direction=numbers(line_no, block.get("direction", []), 3, f"bone {name} direction"),
                    length=float(numbers(line_no, block.get("length", []), 1, f"bone {name} length")[0]),
                    axis=_euler(axis[3], numbers(line_no, axis, 3, f"bone {name} axis"), degrees),
                    dofs=[d.lower() for d in block.get("dof", [])],
                )
                bad = [d for d in bones[name].dofs if d not in ("rx", "ry", "rz")]
                if bad:
                    raise fail(line_no, f"bone {name}: unsupported dof(s) {', '.join(bad)} (rotations only)")
                block = None
            elif block is not None and tokens[0] in ("name", "direction", "length", "axis", "dof"):
                block[tokens[0]] = tokens[1:]
        elif section == "hierarchy" and tokens[0] not in ("begin", "end"):
            children.setdefault(tokens[0], []).extend(tokens[1:])
    if not bones:
        raise InputError(f"{path}: no :bonedata bones; not an ASF skeleton file")
    if "root" not in children:
        raise InputError(f"{path}: :hierarchy does not start at 'root'")
    unknown = sorted({c for cs in children.values() for c in cs} - set(bones))
    if unknown:
        raise InputError(f"{path}: :hierarchy names bones with no :bonedata entry: {', '.join(unknown)}")
    root_axis = _euler(root_axis_order, root_orientation, degrees)
    return AsfSkeleton(path, length_unit, degrees, root_order, root_axis, root_position, bones, children)


@dataclasses.dataclass
class AmcMotion:
    """Per-bone dof values: ``values[bone]`` is (F, number of that bone's dofs); root has its ``order`` dofs."""

    path: Path
    values: dict[str, np.ndarray]

    @property
    def frames(self) -> int:
        return len(self.values["root"])


def read_amc(path: str | Path, skeleton: AsfSkeleton) -> AmcMotion:
    path = Path(path)
    expected = {name: len(bone.dofs) for name, bone in skeleton.bones.items() if bone.dofs}
    expected["root"] = len(skeleton.root_order)
    frames: list[dict[str, list[float]]] = []
    for line_no, raw in enumerate(_read_lines(path), start=1):
        line = raw.strip()
        if not line or line.startswith(("#", ":")):
            continue
        tokens = line.split()
        if len(tokens) == 1 and tokens[0].isdigit():
            frames.append({})
            continue
        if not frames:
            raise InputError(f"{path}: line {line_no}: bone values before the first frame number")
        name = tokens[0]
        if name not in expected:
            raise InputError(f"{path}: line {line_no}: bone {name!r} is not animated in {skeleton.path.name}")
        if len(tokens) - 1 != expected[name]:
            raise InputError(f"{path}: line {line_no}: bone {name} has {len(tokens) - 1} values, the skeleton "
                             f"declares {expected[name]} dofs")
        try:
            frames[-1][name] = [float(v) for v in tokens[1:]]
        except ValueError:
            raise InputError(f"{path}: line {line_no}: non-numeric value in {line!r}") from None
    if not frames:
        raise InputError(f"{path}: no frames")
    incomplete = [i + 1 for i, f in enumerate(frames) if set(f) != set(expected)]
    if incomplete:
        missing = sorted(set(expected) - set(frames[incomplete[0] - 1]))
        raise InputError(f"{path}: {len(incomplete)} frame(s) incomplete or truncated (first: frame "
                         f"{incomplete[0]}, missing {', '.join(missing)})")
    return AmcMotion(path, {name: np.array([f[name] for f in frames]) for name in expected})


def asf_positions(skeleton: AsfSkeleton, motion: AmcMotion) -> tuple[KinematicTree, np.ndarray]:
    """Forward kinematics: the tree (root + one node per bone END) and (F, N, 3) positions in file units."""
    frames = motion.frames
    names, parents = ["root"], [-1]
    queue = list(skeleton.children.get("root", []))
    parent_of = {child: "root" for child in queue}
    while queue:
        name = queue.pop(0)
        names.append(name)
        parents.append(names.index(parent_of[name]))
        for child in skeleton.children.get(name, []):
            parent_of[child] = name
            queue.append(child)
    rotations = np.empty((frames, len(names), 3, 3))
    translations = np.empty((frames, len(names), 3))

    root = motion.values["root"]
    order = skeleton.root_order
    root_rotation_axes = "".join(c[1] for c in order if c.startswith("R"))
    root_angles = np.stack([root[:, k] for k, c in enumerate(order) if c.startswith("R")], -1)
    root_m = _euler(root_rotation_axes, root_angles, skeleton.degrees)
    c = skeleton.root_axis
    rotations[:, 0] = c @ root_m @ c.T
    translations[:, 0] = skeleton.root_position + np.stack([root[:, order.index(f"T{a}")] for a in "XYZ"], -1)
    for i, name in enumerate(names[1:], start=1):
        bone = skeleton.bones[name]
        local = np.broadcast_to(np.eye(3), (frames, 3, 3))
        if bone.dofs:
            m = _euler("".join(d[1] for d in bone.dofs), motion.values[name], skeleton.degrees)
            local = bone.axis @ m @ bone.axis.T
        rotations[:, i] = local
        # The bone vector turns with the bone's own rotation: W_parent (L v).
        translations[:, i] = local @ (bone.direction * bone.length)
    tree = KinematicTree(names, parents, np.zeros((len(names), 3)))
    return tree, tree.forward_kinematics(rotations, translations)
