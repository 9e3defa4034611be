"""World 3D out: JSON, CSV and npz, each stating its units, axes, joint names, frame rate and camera.
Written atomically; an existing file is replaced only when asked."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.lift import LiftResult
from ray3d.skeleton import H36M17

FORMATS = (".json", ".csv", ".npz")
AXES = "world frame, right-handed: x and y horizontal, z up, floor at z = 0"


def _metadata(camera: Camera, fps: float, model: str) -> dict:
    return {"units": "metres", "axes": AXES, "joint_names": list(H36M17.joint_names), "fps": fps,
            "camera": camera.to_dict(), "model": model}


def _rows(results: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stacked (joints (N, 17, 3), frames (N,), tracks (N,), interpolated (N, 17)) over all tracks."""
    joints = np.concatenate([r.joints for r in results.values()])
    frames = np.concatenate([r.frames for r in results.values()])
    tracks = np.concatenate([[str(t)] * len(r.joints) for t, r in results.items()])
    interpolated = np.concatenate([r.interpolated for r in results.values()])
    return joints, frames, tracks, interpolated


def write_world(path: str | Path, results: dict[object, LiftResult], camera: Camera, model: str,
                overwrite: bool = False) -> Path:
    """Write every track's world joints to ``path`` (.json, .csv or .npz by its suffix)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InputError(f"{path}: unknown output format {suffix or '(none)'}; use one of {', '.join(FORMATS)}")
    fps = next(iter(results.values())).fps
    meta = _metadata(camera, fps, model)
    joints, frames, tracks, interpolated = _rows(results)
    with atomic_path(path, overwrite) as temporary:
        if suffix == ".json":
            document = {**meta, "tracks": {str(t): {"frames": r.frames.tolist(),
                                                    "joints": np.round(r.joints, 5).tolist(),
                                                    "interpolated_input_joints": r.interpolated.astype(int).tolist()}
                                           for t, r in results.items()}}
            temporary.write_text(json.dumps(document))
        elif suffix == ".csv":
            with temporary.open("w", newline="") as handle:
                handle.write(f"# units: metres; axes: {AXES}; fps: {fps:g}; model: {model}; camera: "
                             f"{json.dumps(camera.to_dict())}\n")
                writer = csv.writer(handle)
                writer.writerow(["frame", "track", "joint", "x", "y", "z"])
                for i in range(len(joints)):
                    for j, name in enumerate(H36M17.joint_names):
                        writer.writerow([frames[i], tracks[i], name, *(f"{v:.5f}" for v in joints[i, j])])
        else:
            with temporary.open("wb") as handle:
                np.savez_compressed(handle, joints=joints.astype(np.float32), frames=frames, tracks=tracks,
                                    interpolated=interpolated, joint_names=np.array(H36M17.joint_names),
                                    units=np.array("metres"), axes=np.array(AXES), fps=np.array(fps),
                                    model=np.array(model), camera_json=np.array(json.dumps(camera.to_dict())))
    return path


def read_world(path: str | Path) -> dict:
    """Read back what :func:`write_world` wrote: {"joints", "frames", "tracks", "fps", "joint_names", ...}."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    if suffix == ".json":
        document = json.loads(path.read_text())
        joints, frames, tracks = [], [], []
        for track, entry in document["tracks"].items():
            joints.append(np.array(entry["joints"]))
            frames.append(np.array(entry["frames"]))
            tracks.append(np.array([track] * len(entry["frames"])))
        return {**document, "joints": np.concatenate(joints), "frames": np.concatenate(frames),
                "tracks": np.concatenate(tracks)}
    with path.open() as handle:
        header = handle.readline()
        rows = list(csv.DictReader(handle))
    count = len(rows) // 17
    joints = np.array([[float(r[a]) for a in "xyz"] for r in rows]).reshape(count, 17, 3)
    return {"header": header, "joints": joints, "frames": np.array([int(r["frame"]) for r in rows[::17]]),
            "tracks": np.array([r["track"] for r in rows[::17]])}
