"""``ray3d bench real-near``: real footage from near, low cameras against 3D truth (``../shared/data/real-near``:
one man balancing, four calibrated views 2.7-4.1 m away, triangulated truth). Each camera alone, as a user would
run ``ray3d video`` on it: how well the person finder sees the man (frames detected, tracks he became, joints'
distance from the projected truth, time per frame), and how well he is lifted (Abs-MPJPE over the joints the
truth measures, the pelvis's error on the floor plan, the share of frames whose true pelvis lies within 1 and 2
stated sds along the camera's ray) beside the no-learning guess from the same detections (the
mid-ankle pixel's ray meeting the floor: ``ray3d.baselines.floor_guess``); then the views that found him fused into one
world (``ray3d.fusion``).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ray3d import metrics
from ray3d.baselines.floor_guess import floor_guess
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.io.camera_files import read_calibration_toml
from ray3d.io.world import LiftResult, World
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.skeleton import H36M17, convert_keypoints

VIEWS = ("cam01", "cam02", "cam03", "cam04")
CALIBRATION, TRUTH = "calibration_qualisys.toml", "balancing_truth.trc"
# The H36M-17 joints the truth measures, and its marker for each (pelvis: the mid-hips).
TRUTH_MARKERS = {"r_hip": "RHip", "r_knee": "RKnee", "r_ankle": "RAnkle", "l_hip": "LHip", "l_knee": "LKnee",
                 "l_ankle": "LAnkle", "r_shoulder": "RShoulder", "r_elbow": "RElbow", "r_wrist": "RWrist",
                 "l_shoulder": "LShoulder", "l_elbow": "LElbow", "l_wrist": "LWrist"}
SCORED = ("pelvis", *TRUTH_MARKERS)
_SCORED = [H36M17.index(name) for name in SCORED]


def read_truth(path: str | Path) -> np.ndarray:
    """(T, 17, 3) H36M-17 world joints of a Pose2Sim TRC (y up: a point (X, Y, Z) is the world's (Z, X, Y)),
    NaN for the joints it has no marker for."""
    lines = Path(path).read_text().splitlines()
    names = lines[3].split("\t")[2::3]
    values = np.array([[float(v) for v in line.split("\t")[2:2 + 3 * len(names)]]
                       for line in lines[5:] if line.strip()])
    markers = values.reshape(len(values), len(names), 3)[..., [2, 0, 1]]
    joints = np.full((len(markers), H36M17.num_joints, 3), np.nan)
    for joint, marker in TRUTH_MARKERS.items():
        joints[:, H36M17.index(joint)] = markers[:, names.index(marker)]
    joints[:, H36M17.index("pelvis")] = joints[:, [H36M17.index("l_hip"), H36M17.index("r_hip")]].mean(axis=1)
    return joints


def _h36m_pixels(pixels: np.ndarray, confidences: np.ndarray, layout: str) -> np.ndarray:
    """(N, 17, 2) H36M-17 pixels of detections, NaN where a joint was not seen (confidence under 0.5)."""
    h36m, seen = convert_keypoints(pixels, layout, confidences >= 0.5)
    return np.where(seen[..., None], h36m, np.nan)


def _on_the_man(frames: np.ndarray, pixels: np.ndarray, truth_pixels: np.ndarray) -> bool:
    """Whether a track's pelvis lies within the man's projected box (grown by a fifth) in most of its frames."""
    truth = truth_pixels[frames][:, _SCORED]
    low, high = truth.min(axis=1), truth.max(axis=1)
    margin = 0.2 * (high - low)
    pelvis = pixels[:, 0]
    inside = ((pelvis >= low - margin) & (pelvis <= high + margin)).all(axis=-1)
    return bool(inside.mean() > 0.5)


def measure_view(video: Path, camera: Camera, truth: np.ndarray, detector: str,
                 lifter: Lifter) -> tuple[dict, World | None, tuple | None]:
    """One view's row (see the module's description), the man as that view lifts him, and his detections as
    ``Lifter.lift_cameras`` takes them with their layout and rate (None, None if he was not found)."""
    from ray3d.jobs import CameraChoice, Job, video_input
    from ray3d.video import track_video

    info, camera, chosen = video_input(Job((video,), (CameraChoice(made=camera),), detector=detector), 0)
    truth_pixels = camera.project(np.nan_to_num(truth))
    row = {"view": video.stem, "detector": detector, "frames": int(info.frames)}
    started = time.perf_counter()
    try:
        people = track_video(info, camera, chosen, VideoOptions(), progress=False)
    except InputError as err:
        return {**row, "refused": err.message,
                "ms_per_frame": 1e3 * (time.perf_counter() - started) / info.frames}, None, None
    row["ms_per_frame"] = 1e3 * (time.perf_counter() - started) / people.frames_read
    converted = {t: (d.frames, _h36m_pixels(d.pixels, d.confidences, people.layout)) for t, d in people.tracks.items()}
    his = {t: c for t, c in converted.items() if _on_the_man(c[0], c[1], truth_pixels)}
    row["tracks"], row["tracks_on_the_man"] = len(people.tracks), len(his)
    if not his:
        return {**row, "frames_detected": 0}, None, None
    frames = np.concatenate([f for f, _ in his.values()])
    errors = np.concatenate([np.linalg.norm(p[:, _SCORED] - truth_pixels[f][:, _SCORED], axis=-1).ravel()
                             for f, p in his.values()])
    row["frames_detected"] = int(len(np.unique(frames)))
    row["median_2d_error_px"] = float(np.nanmedian(errors))
    # His own track: the one whose pelvis keeps nearest his (a close-up man's box holds others' too, and a second
    # track on him can be the longer), the longer of two as near.
    his_track = min(his, key=lambda t: (round(float(np.nanmedian(np.linalg.norm(
        his[t][1][:, 0] - truth_pixels[his[t][0]][:, 0], axis=-1))), -1), -len(his[t][0])))
    lifted = lifter.lift_tracks({his_track: people.tracks[his_track]}, camera, people.layout, people.fps,
                                **LiftOptions().lift_arguments())[his_track]
    row.update(_errors(lifted, truth))
    in_sds = metrics.root_error_in_sds(lifted.joints, truth[lifted.frames], lifted.position_sd, camera)
    row["within_1sd"], row["within_2sd"] = float(np.mean(in_sds[:, 0] <= 1)), float(np.mean(in_sds[:, 0] <= 2))
    row["across_within_1sd"], row["across_within_2sd"] = (float(np.mean(in_sds[:, 1] <= 1)),
                                                          float(np.mean(in_sds[:, 1] <= 2)))
    plane = lifted.refinement["ankle_plane"] if lifted.refinement else None
    if plane:
        row["floor_z_found_m"], row["floor_z_sd_m"] = plane["floor_z_m"], plane["sd_m"]
        row["floor_decision"], row["floor_chance_off"] = plane["decision"], plane["chance_off"]
    frames_seen, pixels_seen = his[his_track]
    guess = floor_guess(pixels_seen, camera)
    true_pelvis = truth[frames_seen, 0]
    reached = np.isfinite(guess).all(-1)
    row["guess_floor_error_m"] = float(np.median(np.linalg.norm(guess[reached, :2] - true_pelvis[reached, :2],
                                                                axis=-1))) if reached.any() else None
    if row["guess_floor_error_m"]:
        row["pelvis_over_guess"] = row["pelvis_floor_error_m"] / row["guess_floor_error_m"]
    row["model"] = lifter.name
    return row, World({video.stem: lifted}, camera, lifter.name), (({video.stem: people.tracks[his_track]}, camera),
                                                                   people.layout, people.fps)


def _errors(lifted: LiftResult, truth: np.ndarray) -> dict:
    """Abs-MPJPE (mm) over the joints the truth measures and the pelvis's median error on the floor plan (m)."""
    predicted, true = lifted.joints, truth[lifted.frames]
    return {"abs_mpjpe_mm": 1e3 * float(np.nanmean(np.linalg.norm(predicted[:, _SCORED] - true[:, _SCORED], axis=-1))),
            "pelvis_floor_error_m": float(np.median(np.linalg.norm(predicted[:, 0, :2] - true[:, 0, :2], axis=-1)))}


def run(data_dir: str | Path, detector: str, lifter: Lifter, views: tuple[str, ...] = VIEWS,
        floor_offset_m: float = 0.0) -> list[dict]:
    """A row per view and, where two or more views found the man, one for the views fused (``ray3d.fusion``,
    the videos being in step: offsets 0). ``floor_offset_m``: every camera given with its z = 0 this far above
    the floor (``Camera.with_origin_at_height``; the truth moved into its frame), as a calibration made on a
    board on a table would be. A last row lifts the views together on one floor (``Lifter.lift_cameras``)."""

    data_dir = Path(data_dir)
    for needed in (CALIBRATION, TRUTH):
        if not (data_dir / needed).is_file():
            raise InputError(f"{data_dir}: no {needed}: not the real-near recording", arguments=("data_dir",))
    truth = read_truth(data_dir / TRUTH) - [0.0, 0.0, floor_offset_m]
    measured = [measure_view(data_dir / f"{view}.mp4", read_calibration_toml(data_dir / CALIBRATION, view)
                             .with_origin_at_height(floor_offset_m), truth, detector, lifter) for view in views]
    for row, *_ in measured:
        row["floor_offset_m"] = floor_offset_m
    rows, worlds = [row for row, *_ in measured], [world for _, world, _ in measured if world is not None]
    if len(worlds) >= 2:
        rows.append(_fused_row(f"fused ({len(worlds)} views)", worlds, truth, detector, lifter))
        seen = {k: view for k, (_, _, view) in enumerate(measured) if view is not None}
        pooled = lifter.lift_cameras({k: view[0] for k, view in seen.items()}, {k: v[1] for k, v in seen.items()},
                                     {k: v[2] for k, v in seen.items()}, **LiftOptions().lift_arguments())
        one_floor = [World(pooled[k], view[0][1], lifter.name) for k, view in seen.items()
                     if not isinstance(pooled[k], InputError)]
        plane = next(iter(pooled.values())).ankle_plane
        rows.append({**_fused_row(f"fused ({len(one_floor)} views, one floor)", one_floor, truth, detector, lifter),
                     "floor_offset_m": floor_offset_m, "floor_z_found_m": plane.floor_z_m, "floor_z_sd_m": plane.sd_m,
                     "floor_decision": plane.decision, "floor_chance_off": plane.chance_off})
    return rows


def _fused_row(name: str, worlds: list[World], truth: np.ndarray, detector: str, lifter: Lifter) -> dict:
    from ray3d.jobs import fuse_and_write

    fusion = fuse_and_write(worlds)
    fused = max(fusion.world.tracks.values(), key=lambda track: len(track.frames))
    return {"view": name, "detector": detector, "tracks_on_the_man": len(fusion.world.tracks),
            "frames_detected": int(len(fused.frames)), **_errors(fused, truth), "model": lifter.name,
            "agreement": fusion.agreement}


COLUMNS = ("view", "detector", "tracks_on_the_man", "frames_detected", "median_2d_error_px", "ms_per_frame",
           "abs_mpjpe_mm", "pelvis_floor_error_m", "guess_floor_error_m", "pelvis_over_guess", "within_1sd",
           "within_2sd", "across_within_1sd", "across_within_2sd", "floor_offset_m", "floor_z_found_m", "floor_z_sd_m",
           "floor_decision", "floor_chance_off")


def write(out_dir: str | Path, rows: list[dict]) -> list[Path]:
    """``real-near.json`` (every row) and ``real-near.md`` (the table)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    def cell(row: dict, key: str) -> str:
        value = row.get(key)
        if key == "tracks_on_the_man" and "refused" in row:
            return f"refused: {row['refused']}"
        return "-" if value is None else f"{value:.3g}" if isinstance(value, float) else str(value)

    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(cell(row, key) for key in COLUMNS) + " |" for row in rows]
    files = [out_dir / "real-near.json", out_dir / "real-near.md"]
    for path, text in zip(files, (json.dumps(rows, indent=1), "\n".join(lines) + "\n")):
        with atomic_path(path, overwrite=True) as temporary:
            temporary.write_text(text)
    return files
