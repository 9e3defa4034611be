"""The evaluation protocol: a model (or RFRH) on clips seen through cameras, GT 2D, per camera, per clip and
overall, in millimetres.

Clips are centred on the world origin in the floor plane (as the virtual grids expect). A (camera, clip) pair
is evaluated only if the camera sees every joint of every frame of the clip; skipped pairs are counted.
Overall values are frame-weighted over all evaluated (camera, clip, frame) triples.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from ray3d import metrics
from ray3d.baselines.rfrh import rfrh_root
from ray3d.body import POSTURES, postures
from ray3d.checkpoints import RFRH, load_model
from ray3d.console import progress_bar
from ray3d.data import motion as motion_data
from ray3d.data.motion import MotionSet
from ray3d.data.samples import SampleConfig, observe, scale_bones
from ray3d.data.virtual_cameras import SET_NAMES, centre_clip, grid
from ray3d.errors import InputError
from ray3d.geometry import Camera, CameraBatch
from ray3d.io.camera_files import load_cameras
from ray3d.models.network import LiftingNetwork, predict_world
from ray3d.models.precision import with_precision
from ray3d.models.tensor_batch import TensorBatch
from ray3d.refine import RefineConfig, joint_directions, network_position_sd, refine_track
from ray3d.skeleton import H36M17, layout_skeleton
from ray3d.temporal import Window, sequence_windows

METRICS = ("mpjpe_mm", "p_mpjpe_mm", "abs_mpjpe_mm", "mrpe_mm")
COVERAGE = ("within_1sd", "within_2sd", "across_within_1sd", "across_within_2sd")
SCORED_LAYOUTS = ("h36m17", "h36m14")


def _window(model: LiftingNetwork | str) -> Window:
    return Window(1) if model == RFRH else model.config.window


@torch.no_grad()
def predict_windows(model: LiftingNetwork | str, windows: np.ndarray, camera: Camera, flip_test: bool = False,
                  chunk: int = 8192, given: Camera | None = None, noise_px: float = 0.0,
                  rng: np.random.Generator | None = None, return_pixels: bool = False):
    """(N, F, J, 3) world windows seen (GT 2D) by ``camera`` -> (N, J, 3) predicted world joints of the target frames
    (centre, or last for a causal model); for RFRH only the root (joint 0) is predicted and the other joints are NaN.

    ``given`` is the camera the model is told about (default: the true one), e.g. a mis-calibrated copy: the
    pixels come from ``camera``, the rays, camera parameters and the way back to the world from ``given``.
    ``noise_px`` adds Gaussian noise (standard deviation in pixels, drawn from ``rng``) to every pixel of every
    window, as a detector's jitter.
    """
    given = given or camera
    if noise_px > 0 and rng is None:
        rng = np.random.default_rng(0)
    window, remove_roll = _window(model), model != RFRH and model.config.remove_roll
    layout = "h36m17" if model == RFRH else model.config.layout
    out, target_pixels = [], []
    for start in range(0, len(windows), chunk):
        part = windows[start:start + chunk]
        batch = observe(part, CameraBatch.repeated(camera, len(part)), window, remove_roll,
                        rng if noise_px > 0 else None, SampleConfig(noise_px=noise_px), layout)
        told, rays = batch.cameras, batch.rays
        if given is not camera:  # the pixels stay the true camera's; everything else is the given camera's
            told = CameraBatch.repeated(given, len(part))
            rays = given.pixels_to_rays(batch.pixels.astype(np.float64), remove_roll=remove_roll)
        if model == RFRH:
            predicted = np.full(part.shape[:1] + part.shape[2:], np.nan)
            predicted[:, 0] = rfrh_root(batch.pixels[:, window.target, 0].astype(np.float64), given)
        else:
            predicted = predict_world(model, TensorBatch.from_arrays(batch.pixels, rays, told), told, flip_test).numpy()
        out.append(predicted)
        target_pixels.append(batch.pixels[:, window.target].astype(np.float64))
    return (np.concatenate(out), np.concatenate(target_pixels)) if return_pixels else np.concatenate(out)


def _per_frame(predicted: np.ndarray, target: np.ndarray, in_sds: np.ndarray | None = None) -> dict[str, np.ndarray]:
    mm = {"mrpe_mm": 1e3 * metrics.mrpe(predicted, target, reduction="none")}
    if in_sds is not None:
        for prefix, column in (("", 0), ("across_", 1)):
            mm.update({f"{prefix}within_{k}sd": (in_sds[:, column] <= k).astype(float) for k in (1, 2)})
    if not np.isnan(predicted[:, 1:]).all():
        mm["mpjpe_mm"] = 1e3 * metrics.mpjpe(predicted, target, reduction="none")
        mm["p_mpjpe_mm"] = 1e3 * metrics.p_mpjpe(predicted, target, reduction="none")
        mm["abs_mpjpe_mm"] = 1e3 * metrics.abs_mpjpe(predicted, target, reduction="none")
    return mm


def _summarise(parts: list[dict[str, np.ndarray]]) -> dict:
    frames = sum(len(p["mrpe_mm"]) for p in parts)
    summary = {"frames": int(frames)}
    for key in METRICS + COVERAGE:
        values = [p[key] for p in parts if key in p]
        summary[key] = float(np.concatenate(values).mean()) if values else None
    return summary


def _check_cameras(cameras, given_cameras) -> None:
    """``cameras`` a non-empty list of ``Camera``s, and ``given_cameras`` none or one ``Camera`` for each."""
    for name, listed in (("cameras", cameras), ("given_cameras", given_cameras or cameras)):
        if isinstance(listed, (str, Camera)) or not isinstance(listed, (list, tuple)) or not listed \
                or not all(isinstance(c, Camera) for c in listed):
            raise InputError(f"{name}: expected a non-empty list of Camera objects (evaluation_cameras reads a set "
                             f"or a file), got {type(listed).__name__}", (name,))
    if given_cameras and len(given_cameras) != len(cameras):
        raise InputError(f"given_cameras: expected one for each of the {len(cameras)} cameras, got "
                         f"{len(given_cameras)}", ("given_cameras",))


def _check_number(name: str, value, expected: str, holds) -> None:
    """``value`` a finite number for which ``holds``, else an ``InputError`` naming the argument ``name``."""
    number = not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
    if not (number and np.isfinite(value) and holds(value)):
        raise InputError(f"{name}: expected a finite number {expected}, got {value!r:.40}", (name,))


def evaluate(model: LiftingNetwork | str, motion: MotionSet, cameras: list[Camera], flip_test: bool = False,
             frame_stride: int = 1, given_cameras: list[Camera] | None = None, bone_scale: float = 1.0,
             joints: str = "h36m17", noise_px: float = 0.0, seed: int = 0, refine: bool | RefineConfig = False,
             progress: bool = False, precision: str = "fp32") -> dict:
    """Metrics of ``model`` (a network, a checkpoint name or path, or ``"rfrh"``) over every (camera, clip).

    ``given_cameras`` (one per camera) are what the model is told instead of the true cameras (calibration
    error); ``bone_scale`` multiplies every bone of every clip, re-grounded (smaller or larger people);
    ``joints="h36m14"`` scores only the 14 joints common to most datasets (no spine, thorax, neck/nose);
    ``noise_px`` perturbs the 2D input like a detector's jitter (see ``predict_windows``; ``seed`` fixes it);
    ``refine`` lifts each (camera, clip) as one track with the track-level refinement (``ray3d.refine``), at the
    clip's rate over ``frame_stride`` (a ``RefineConfig`` sets its uncertainties; ``True`` takes the defaults
    with ``keypoint_error`` 0 for GT 2D, since the joints' rays are then exact). ``progress`` shows a bar over the
    cameras. ``within_1sd`` / ``within_2sd``: the share of frames whose root lies within 1 / 2 of its reported standard
    deviation along its ray (``across_...``: across it; ``ray3d.metrics.root_error_in_sds``), with or without
    the refinement; not for RFRH. ``precision``: the network's arithmetic (``models.precision``: fp32, bf16,
    int8). ``per_posture``: the same
    measures for the frames whose true pose is upright, sitting or crouching, lying, or airborne
    (``ray3d.body.postures``).
    """
    if refine and model == RFRH:
        raise InputError("refine: needs a model that predicts every joint; rfrh predicts only the root",
                         ("refine", "model"))
    if precision != "fp32" and model == RFRH:
        raise InputError(f"precision: {precision} needs a network; rfrh has none (fp32 only)", ("precision",))
    rng = np.random.default_rng(seed)
    if isinstance(frame_stride, bool) or not isinstance(frame_stride, (int, np.integer)) or frame_stride < 1:
        raise InputError(f"frame_stride: expected a whole number of frames, at least 1, got {frame_stride!r}",
                         arguments=("frame_stride",))
    if joints not in SCORED_LAYOUTS:
        raise InputError(f"joints: expected one of {', '.join(SCORED_LAYOUTS)}, got {joints!r:.40}", ("joints",))
    _check_cameras(cameras, given_cameras)
    _check_number("bone_scale", bone_scale, "above 0", lambda v: v > 0)
    _check_number("noise_px", noise_px, "0 or more", lambda v: v >= 0)
    scored = [H36M17.index(name) for name in layout_skeleton(joints).joint_names]
    document = {}
    if isinstance(model, str) and model != RFRH:
        model, document = load_model(model)
    if isinstance(model, LiftingNetwork):
        model = with_precision(model, precision)
    window = _window(model)
    # GT 2D is exact: the refinement may put each joint on its ray; noisy 2D is weighed as a detector's.
    refine_config = (refine if isinstance(refine, RefineConfig)
                     else RefineConfig.for_model(document, **({"keypoint_error": 0.0} if noise_px == 0 else {})))
    per_camera: dict[str, list] = defaultdict(list)
    per_clip: dict[str, list] = defaultdict(list)
    per_posture: dict[str, list] = defaultdict(list)
    clips = [motion.clip(i).astype(np.float64) for i in range(motion.num_clips)]
    if bone_scale != 1.0:
        clips = [scale_bones(clip, np.full(clip.shape[:2], bone_scale)) for clip in clips]
    clips = [centre_clip(clip) for clip in clips]
    given_cameras = given_cameras or cameras
    windows = [sequence_windows(clip, window)[::frame_stride] for clip in clips]
    skipped = 0
    for camera, given in progress_bar(list(zip(cameras, given_cameras)), shown=progress, desc="evaluating",
                                      unit="camera", leave=False):
        # All clips this camera sees go through the network together; errors are split back per clip.
        seen = [i for i, clip in enumerate(clips) if camera.sees(clip)]
        skipped += len(clips) - len(seen)
        if not seen:
            continue
        stacked = np.concatenate([windows[i] for i in seen])
        predicted = predict_windows(model, stacked, camera, flip_test, given=given, noise_px=noise_px, rng=rng,
                                    return_pixels=refine)
        bounds = np.cumsum([0] + [len(windows[i]) for i in seen])
        in_sds = None
        if refine:
            predicted, pixels = predicted
            position_sd = np.zeros((len(predicted), 2))
            for k, i in enumerate(seen):
                track = slice(bounds[k], bounds[k + 1])
                rays = joint_directions(given, pixels[track], model.config.input_skeleton)
                predicted[track], found = refine_track(predicted[track], given,
                                                       float(motion.clips["fps"][i]) / frame_stride, rays,
                                                       config=refine_config)
                position_sd[track] = found.position_sd_m
        elif model != RFRH:
            position_sd = network_position_sd(predicted, given, refine_config)
        if model != RFRH:
            in_sds = metrics.root_error_in_sds(predicted, stacked[:, window.target], position_sd, camera)
        errors = _per_frame(predicted[:, scored], stacked[:, window.target][:, scored], in_sds)
        classes = postures(stacked[:, window.target])
        for k, name in enumerate(POSTURES):
            if (classes == k).any():
                per_posture[name].append({key: value[classes == k] for key, value in errors.items()})
        for k, i in enumerate(seen):
            part = {key: value[bounds[k]:bounds[k + 1]] for key, value in errors.items()}
            per_camera[camera.name].append(part)
            per_clip[str(motion.clips["clip_id"][i])].append(part)
    if not per_camera:
        raise InputError(f"cameras: none of the {len(cameras)} camera(s) sees any of the {len(clips)} clip(s) "
                         "entirely: nothing to evaluate (the clips are centred at the origin; point the cameras "
                         "there)", ("cameras",))
    everything = [e for parts in per_camera.values() for e in parts]
    geometry = {c.name: {"height_m": c.camera_height, "pitch_deg": float(np.degrees(c.pitch)),
                         "horizontal_distance_m": float(np.linalg.norm(c.center[:2]))} for c in cameras}
    return {**_summarise(everything), "pairs": len(everything), "skipped_pairs": skipped, "flip_test": flip_test,
            "frame_stride": frame_stride, "joints": joints, "noise_px": noise_px, "refine": bool(refine),
            "refine_config": dataclasses.asdict(refine_config) if refine else None,
            "per_camera": {name: {**_summarise(parts), **geometry[name]} for name, parts in per_camera.items()},
            "per_clip": {name: _summarise(parts) for name, parts in per_clip.items()},
            "per_posture": {name: _summarise(per_posture[name]) for name in POSTURES if name in per_posture}}


def evaluation_motion(mocap: str | Path | None = None, split: str | None = None,
                      datasets: tuple[str, ...] | None = None,
                      data_dir: str | Path | None = None) -> tuple[MotionSet, str]:
    """The clips to evaluate on and a description of them: the shipped mocap's ``split`` (default the test
    performers) of ``datasets`` (default all), or a motion npz of one's own (its ``split``: default ``test`` for
    a shipped file, every clip for any other)."""
    if mocap is None:
        datasets = tuple(datasets or motion_data.DATASETS)
        clips = motion_data.load_shipped(data_dir, split or "test", datasets)
        source = f"shipped mocap ({', '.join(datasets)}), {split or 'test'} performers"
    else:
        mocap = Path(mocap)
        split = split or ("test" if mocap.name in motion_data.SHIPPED_FILES else "all")
        clips = motion_data.select_split(MotionSet.load(mocap), split)
        source = f"{mocap} ({split} clips)"
    if clips.num_clips == 0:
        raise InputError(f"{source}: no clips to evaluate")
    return clips, source


def evaluation_cameras(spec: str | Path) -> list[Camera]:
    """A named camera set (``extrinsic-test``, ``h36m``, ...) or the cameras of a JSON file."""
    return grid(str(spec)) if str(spec) in SET_NAMES else load_cameras(spec)
