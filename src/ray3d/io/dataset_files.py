"""Dataset files users bring: VideoPose3D-style Human3.6M npz files and the same nested layout for
MPI-INF-3DHP and HumanEva (brief section 9). Their data may not be shipped; tests use generated fixtures.
``ray3d.data.motion.to_motion_set`` turns 3D positions into clips to evaluate on; ``ray3d.io.keypoints`` reads
the 2D files for lifting.

3D files: key ``positions_3d`` -> {subject: {action: float (N, J, 3)}}, world metres. 2D files: key
``positions_2d`` -> {subject: {action: [one (N, J, 2) pixel array per camera]}} plus ``metadata``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ray3d.errors import InputError, reads_file
from ray3d.geometry import y_up_to_z_up
from ray3d.io.safe_npz import read_npz_entries
from ray3d.skeleton import convert

H36M32_TO_17 = (0, 1, 2, 3, 6, 7, 8, 12, 13, 14, 15, 17, 18, 19, 25, 26, 27)
H36M_2D_CAMERA_ORDER = ("54138969", "55011271", "58860488", "60457274")
DATASET_FPS = {"h36m": 50.0, "3dhp": 50.0, "humaneva": 60.0}
# Joint count -> (source layout, layout we convert to) per dataset.
_LAYOUTS = {
    ("h36m", 32): (None, "h36m17"), ("h36m", 17): ("h36m17", "h36m17"),
    ("3dhp", 17): ("3dhp17", "h36m17"), ("humaneva", 15): ("humaneva15", "h36m14"),
}


def _nested(path: Path, key: str, entries: dict) -> dict:
    if key not in entries:
        raise InputError(f"{path}: missing key {key!r} (found: {', '.join(entries) or 'nothing'})")
    nested = entries[key]
    if not isinstance(nested, dict) or not all(isinstance(v, dict) for v in nested.values()):
        raise InputError(f"{path}: {key} must be a dict {{subject: {{action: array}}}}")
    return nested


def _to_layout(array, dataset: str, path: Path, where: str, up: str) -> np.ndarray:
    """One (frames, joints, 2 or 3) array in the layout we use; 2D detections may miss joints (NaN)."""
    array = np.asarray(array, dtype=np.float64)
    if array.ndim != 3 or array.shape[-1] not in (2, 3):
        raise InputError(f"{path}: {where}: expected (frames, joints, 2 or 3), got {array.shape}")
    layouts = _LAYOUTS.get((dataset, array.shape[1]))
    if layouts is None:
        known = sorted(j for d, j in _LAYOUTS if d == dataset)
        raise InputError(f"{path}: {where}: {array.shape[1]} joints is not a {dataset} layout (expected {known})")
    if np.isinf(array).any() or (array.shape[-1] == 3 and np.isnan(array).any()):
        raise InputError(f"{path}: {where}: contains NaN or infinite values")
    if up == "y" and array.shape[-1] == 3:
        array = y_up_to_z_up(array)
    source, target = layouts
    return array[:, list(H36M32_TO_17)] if source is None else convert(array, source, target)


@reads_file("positions_3d file")
def load_positions_3d(path: str | Path, dataset: str = "h36m", up: str = "z") -> dict[str, dict[str, np.ndarray]]:
    """{subject: {action: (N, J, 3)}} in metres, z up: Human3.6M's 32 joints and 3DHP's 17 become H36M-17,
    HumanEva's 15 the 14-joint cross-dataset layout. ``up="y"`` rotates y-up files to z-up."""
    path = Path(path)
    if dataset not in DATASET_FPS:
        raise InputError(f"unknown dataset {dataset!r}; one of {', '.join(DATASET_FPS)}")
    if up not in ("z", "y"):
        raise InputError(f"up must be 'z' or 'y', got {up!r}")
    return {str(subject): {str(action): _to_layout(array, dataset, path, f"{subject}/{action}", up)
                           for action, array in actions.items()}
            for subject, actions in _nested(path, "positions_3d", read_npz_entries(path)).items()}


@reads_file("positions_2d file")
def load_positions_2d(path: str | Path, dataset: str = "h36m",
                      entries: dict | None = None) -> tuple[dict[str, dict[str, list[np.ndarray]]], dict]:
    """({subject: {action: [(N, J, 2) per camera]}}, metadata); Human3.6M cameras in H36M_2D_CAMERA_ORDER.
    ``entries``: the file's entries when they have been read already."""
    path = Path(path)
    entries = read_npz_entries(path) if entries is None else entries
    nested = _nested(path, "positions_2d", entries)
    out = {}
    for subject, actions in nested.items():
        out[str(subject)] = {}
        for action, per_camera in actions.items():
            if not isinstance(per_camera, (list, tuple)):
                raise InputError(f"{path}: {subject}/{action}: expected a list with one array per camera")
            out[str(subject)][str(action)] = [
                _to_layout(a, dataset, path, f"{subject}/{action}/camera {i}", "z") for i, a in enumerate(per_camera)]
    metadata = entries.get("metadata", {})
    return out, metadata if isinstance(metadata, dict) else {}
