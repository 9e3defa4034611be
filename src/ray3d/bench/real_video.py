"""``ray3d bench real-video``: the physical checks (``bench/physical.py``) of the people lifted from a real video
with its calibration, where there is no ground truth, and from a detector-emulated copy of the mocap test split,
where the errors against the truth are measured as well; each with the track-level refinement off and on.

The emulation: each test clip seen by a random camera mounted as users mount them (2.5-10 m high, 6-35 m away),
2D with a detector's jitter (0.5 px plus 1.5 % of the person's height in the image) and 2 % of joints missed, in
the layout the model reads: H36M-17, or COCO-17 (face points placed as in training) for a detector-native model.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d import metrics
from ray3d.bench.physical import CHECKS, summarise, track_checks
from ray3d.body import HEAD_OVER_ANKLE_OF_STATURE
from ray3d.data.detector_emulation import body_frames, detector_offsets, detector_points, offset_joints
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import CameraRanges, centre_clip, sample_cameras
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions
from ray3d.skeleton import COCO17, H36M17, Skeleton, layout_skeleton

EMULATED_CAMERAS = CameraRanges(height_m=(2.5, 10.0), distance_m=(6.0, 35.0), pitch_deg=(0.0, 40.0), roll_deg=3.0,
                                hfov_deg=(30.0, 70.0), image_size=(1280, 720), principal_offset_px=20.0,
                                aim_fov_fraction=0.3)
EMULATED_NOISE = (0.5, 0.015)  # pixels, and a fraction of the person's height in the image
EMULATED_MISSES = 0.02
EMULATED_FPS = 30.0            # the clips (60 fps) are seen at a surveillance camera's rate
REFINE = (False, True)


def emulated_detections(clip: np.ndarray, camera: Camera, rng: np.random.Generator,
                        layout: Skeleton = H36M17, offset_scale: float = 0.0) -> np.ndarray:
    """(T, J, 2) pixels of ``layout`` of a (T, 17, 3) H36M-17 clip as a detector would report them (NaN where
    missed, and where outside the image). ``offset_scale``: how much of a detector's measured joint offsets from
    the mocap's joint centres (``ray3d.data.samples.DETECTOR_JOINT_OFFSETS_M``) the detector has."""
    points = detector_points(clip, layout)
    if offset_scale:
        points = offset_joints(points[None], body_frames(clip)[None], offset_scale * detector_offsets(layout)[None],
                               layout)[0]
    pixels = camera.project(points)
    height = np.ptp(pixels[..., 1], axis=1)
    noisy = pixels + (rng.normal(0.0, 1.0, pixels.shape)
                      * (EMULATED_NOISE[0] + EMULATED_NOISE[1] * height)[:, None, None])
    missed = rng.random(pixels.shape[:2]) < EMULATED_MISSES
    # The pelvis, or the hips it comes from, is kept, so that every frame has a root.
    root = ["pelvis"] if "pelvis" in layout.joint_names else ["l_hip", "r_hip"]
    outside = ((pixels < 0) | (pixels > np.asarray(camera.image_size) - 1)).any(-1)
    unseen = missed | outside
    unseen[:, [layout.index(name) for name in root]] = False
    return np.where(unseen[..., None], np.nan, noisy)


def emulated_layout(lifter: Lifter) -> Skeleton:
    """What the emulated detector reports for ``lifter``: H36M-17 for a model that reads it, else COCO-17."""
    return H36M17 if lifter.model.config.input_skeleton.name == H36M17.name else COCO17


def _camera_seeing(clip: np.ndarray, rng: np.random.Generator, attempts: int = 50) -> Camera | None:
    for _ in range(attempts):
        camera = sample_cameras(clip[len(clip) // 2, :1], rng, EMULATED_CAMERAS).camera(0)
        if camera.sees(clip):
            return camera
    return None


def run_emulated(lifter: Lifter, motion: MotionSet, pairs: int = 12, seed: int = 0,
                 max_frames: int = 600, smooth_3d: str | None = None, layout: str | None = None) -> list[dict]:
    """One row per (clip, camera, refinement): the errors against the truth and the physical checks
    (``smooth_3d`` as for ``Lifter.lift``); the detector reports ``layout`` (default: ``emulated_layout``)."""
    rng = np.random.default_rng(seed)
    step = int(round(60.0 / EMULATED_FPS))
    rows = []
    for pair in range(pairs):
        clip = centre_clip(motion.clip(pair % motion.num_clips).astype(np.float64))[:max_frames:step]
        camera = _camera_seeing(clip, rng)
        if camera is None:
            continue
        seen = layout_skeleton(layout) if layout else emulated_layout(lifter)
        pixels = emulated_detections(clip, camera, rng, seen)
        distance = float(np.median(np.linalg.norm(clip[:, 0] - camera.center, axis=-1)))
        for refine in REFINE:
            result = lifter.lift(pixels, camera, fps=EMULATED_FPS, layout=seen.name, refine=refine,
                                 smooth_3d=smooth_3d)
            rows.append({"pair": pair, "clip": str(motion.clips["clip_id"][pair % motion.num_clips]),
                         "refine": refine, "camera_height_m": camera.camera_height, "distance_m": distance,
                         "mrpe_mm": 1e3 * float(metrics.mrpe(result.joints, clip)),
                         "abs_mpjpe_mm": 1e3 * float(metrics.abs_mpjpe(result.joints, clip)),
                         "mpjpe_mm": 1e3 * float(metrics.mpjpe(result.joints, clip)),
                         "mrpe_of_distance_pct": 100 * float(metrics.mrpe(result.joints, clip)) / distance,
                         **_coverage(metrics.root_error_in_sds(result.joints, clip, result.position_sd, camera)),
                         **track_checks(result)})
    return rows


def _coverage(in_sds: np.ndarray) -> dict:
    """The shares of frames whose true root lies within 1 and 2 of its reported sds, along its ray and across."""
    return {"within_1sd": float(np.mean(in_sds[:, 0] <= 1)), "within_2sd": float(np.mean(in_sds[:, 0] <= 2)),
            "across_within_1sd": float(np.mean(in_sds[:, 1] <= 1)),
            "across_within_2sd": float(np.mean(in_sds[:, 1] <= 2))}


def run_video(lifter: Lifter, keypoints, camera: Camera, smooth_3d: str | None = None) -> list[dict]:
    """One row per (track, refinement) of the detections of a video (``ray3d.io.keypoints.Keypoints``)."""
    rows = []
    for refine in REFINE:
        world = lifter.lift_keypoints(keypoints, camera, LiftOptions(smooth_3d=smooth_3d, refine=refine))
        rows += [{"track": track, "refine": refine, **track_checks(result)} for track, result in world.tracks.items()]
    return rows


def _table(title: str, groups: dict[str, list[dict]], extra: tuple[str, ...] = ()) -> list[str]:
    keys = extra + CHECKS[1:]
    lines = [f"### {title}", "", "| refinement | tracks | frames | " + " | ".join(keys) + " |",
             "|---" * (len(keys) + 3) + "|"]
    for name, rows in groups.items():
        summary = summarise(rows)
        cells = [f"{np.median([r[k] for r in rows]):.3g}" if k in extra else f"{summary[k]:.3g}" for k in keys]
        lines.append(f"| {name} | {summary['tracks']} | {summary['frames']} | " + " | ".join(cells) + " |")
    return lines + [""]


def write(out_dir: str | Path, emulated: list[dict], video: list[dict] | None = None,
          video_name: str = "") -> list[Path]:
    """``real-video.json`` (every row) and ``real-video.md`` (the tables: medians over tracks)."""
    out_dir = Path(out_dir)
    lines = ["Medians over tracks, except the floor fraction (over person-frames). Stature = head over the lowest "
             f"ankle / {HEAD_OVER_ANKLE_OF_STATURE:.3f}.", ""]
    if video:
        lines += _table(f"{video_name} (no ground truth)",
                        {("on" if r else "off"): [row for row in video if row["refine"] == r] for r in REFINE})
    lines += _table("detector-emulated mocap test split",
                    {("on" if r else "off"): [row for row in emulated if row["refine"] == r] for r in REFINE},
                    ("mrpe_mm", "abs_mpjpe_mm", "mrpe_of_distance_pct"))
    for refine in REFINE:
        rows = [row for row in emulated if row["refine"] == refine]
        if rows:
            weights = [row["frames"] for row in rows]
            share = {key: 100 * np.average([row[key] for row in rows], weights=weights)
                     for key in ("within_1sd", "within_2sd", "across_within_1sd", "across_within_2sd")}
            lines.append(f"Refinement {'on' if refine else 'off'}: the true root within the reported sd along its ray "
                         f"in {share['within_1sd']:.1f} % of person-frames within 1 sd, {share['within_2sd']:.1f} % "
                         f"within 2; across it {share['across_within_1sd']:.1f} % / "
                         f"{share['across_within_2sd']:.1f} %.")
    lines.append("")
    files = [out_dir / "real-video.json", out_dir / "real-video.md"]
    with atomic_path(files[0], overwrite=True) as temporary:
        temporary.write_text(json.dumps({"video": video_name, "video_rows": video or [], "emulated_rows": emulated},
                                        indent=1, default=str))
    with atomic_path(files[1], overwrite=True) as temporary:
        temporary.write_text("\n".join(lines))
    return files
