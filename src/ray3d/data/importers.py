"""Users' own motion capture (BVH, ASF/AMC) -> H36M-17 joint positions in metres, z up, floor at z = 0.

The steps, in order (mocap README section 7): forward kinematics in file units; mapping to H36M-17; conversion
to metres; axis change (x, y, z) -> (x, -z, y) from the files' y-up; dropping leading synthetic frames;
resampling to the chosen frame rate; and (optionally) shifting z so the floor is at 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ray3d.body import ANKLES, HEAD, PELVIS, head_over_ankle
from ray3d.data import asf_amc, bvh, mapping
from ray3d.data.motion import MotionSet
from ray3d.data.skeleton_fk import KinematicTree
from ray3d.errors import InputError, reads_file
from ray3d.geometry import y_up_to_z_up
from ray3d.temporal import resample

UNITS_M = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
DEFAULT_BVH_UNITS = {"cgspeed-motionbuilder": "cmu", "cgspeed-3dsmax": "cmu", "cgspeed-daz": "cm", "ray3d": "m"}
FLOOR_PERCENTILE = 2.0  # of the per-frame lowest foot point: robust to the odd jump or glitch
PLAUSIBLE_BODY_HEIGHT_M = (0.5, 2.6)


@dataclasses.dataclass
class ImportedClip:
    """One imported take: ``positions`` (F, 17, 3) metres, z up, at ``fps``."""

    positions: np.ndarray
    fps: float
    native_fps: float
    native_frames: int
    dropped_native_frames: int
    floor_offset_m: float
    source_file: str
    naming: str


def _finish(tree: KinematicTree, nodes: np.ndarray, naming: mapping.Naming, unit_m: float, native_fps: float,
            fps: float, drop_native_frames: int, floor: bool, source: str) -> ImportedClip:
    if fps <= 0:
        raise InputError(f"{source}: fps must be positive, got {fps}")
    if not 0 <= drop_native_frames < len(nodes):
        raise InputError(f"{source}: cannot drop {drop_native_frames} of {len(nodes)} frames")
    joints = y_up_to_z_up(mapping.to_h36m17(tree, nodes, naming) * unit_m)
    feet = y_up_to_z_up(nodes[:, mapping.foot_nodes(tree, naming)] * unit_m)
    joints, feet = joints[drop_native_frames:], feet[drop_native_frames:]
    joints, feet = resample(joints, native_fps, fps), resample(feet, native_fps, fps)
    height = np.median(head_over_ankle(joints))
    chain = np.median(np.linalg.norm(joints[:, HEAD] - joints[:, PELVIS], axis=-1) + np.linalg.norm(
        joints[:, PELVIS] - joints[:, ANKLES[1]], axis=-1))
    low, high = PLAUSIBLE_BODY_HEIGHT_M
    if not low <= chain <= high:
        raise InputError(f"{source}: the body comes out {chain:.2f} m from ankle to head (standing height "
                         f"{height:.2f} m) with {unit_m} m per file unit; pass the file's units (one of "
                         f"{', '.join(UNITS_M)})")
    offset = float(np.percentile(feet[..., 2].min(axis=1), FLOOR_PERCENTILE)) if floor and not naming.floor_at_zero \
        else 0.0
    joints = joints - np.array([0.0, 0.0, offset])
    return ImportedClip(joints.astype(np.float32), fps, native_fps, len(nodes), drop_native_frames, offset, source,
                        naming.name)


@reads_file("BVH file")
def import_bvh(path: str | Path, fps: float = 60.0, drop_native_frames: int = 0, floor: bool = True,
               units: str | None = None) -> ImportedClip:
    """Import a BVH take (cgspeed MotionBuilder, 3dsMax or Daz naming, or ray3d's own export, whose floor is
    already at 0).

    Args:
        fps: output frame rate.
        drop_native_frames: leading frames to discard (e.g. a synthetic T-pose), counted at the file's rate.
        floor: shift z so the floor (2nd percentile of the lowest foot point) is at 0.
        units: file length units (``m, cm, mm, inch, cmu``); default by naming (cgspeed: CMU units; Daz: cm;
            ray3d: m).
    """
    motion = bvh.read_bvh(path)
    naming = mapping.detect_naming(motion.tree, str(path))
    units = units or DEFAULT_BVH_UNITS.get(naming.name, "cm")
    if units not in UNITS_M:
        raise InputError(f"{path}: unknown units {units!r}; one of {', '.join(UNITS_M)}")
    return _finish(motion.tree, motion.positions(), naming, UNITS_M[units], motion.fps, fps, drop_native_frames,
                   floor, str(path))


@reads_file("ASF/AMC file")
def import_amc(asf_path: str | Path, amc_path: str | Path, fps: float = 60.0, native_fps: float = 120.0,
               drop_native_frames: int = 0, floor: bool = True) -> ImportedClip:
    """Import an ASF/AMC take (CMU or HDM05 conventions). AMC files do not state their rate: ``native_fps``
    (120 for CMU and HDM05)."""
    skeleton = asf_amc.read_asf(asf_path)
    motion = asf_amc.read_amc(amc_path, skeleton)
    tree, nodes = asf_amc.asf_positions(skeleton, motion)
    naming = mapping.detect_naming(tree, str(asf_path))
    return _finish(tree, nodes, naming, skeleton.metres_per_unit, native_fps, fps, drop_native_frames, floor,
                   str(amc_path))


def clips_to_motion_set(clips: list[ImportedClip], names: list[str], subject: str, source: str) -> MotionSet:
    """Imported takes as a motion set in the shipped npz format (one performer, their own skeleton)."""
    return MotionSet.from_clips(
        [c.positions for c in clips], clip_id=names, subject=subject, orig_subject=subject, source=source,
        retargeted=False, fps=[c.fps for c in clips], native_fps=[c.native_fps for c in clips],
        description=[c.source_file for c in clips], floor_offset_m=[c.floor_offset_m for c in clips])
