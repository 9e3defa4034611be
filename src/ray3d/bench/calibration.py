"""How well ``ray3d.calibrate.from_person`` recovers a camera, and what its errors cost Ray3D: the test
performers' walking clips seen by random virtual cameras, GT 2D (clean or noisy), the camera estimated from
the person (or from several people walking at once, fitted jointly), then the clips lifted with the estimated
camera and with the true one.

Both liftings are compared with the truth in the floor frame below the camera (x along the direction it looks,
z up): the only world frame a camera estimated from a person can define, and the one ``Camera.from_height_pitch``
uses. The person's "true" stature is their upright head-joint height over ``AXIS_HEIGHTS["head"]``.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ray3d import metrics
from ray3d.body import ADULT_STATURE_M, AXIS_HEIGHTS
from ray3d.calibrate import from_person
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import CameraRanges, centre_clip, sample_cameras
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.skeleton import H36M17

IMAGE_SIZE = (1920, 1080)
# name -> (focal length given, stature given as the person's own (else the adult default), 2D noise in px)
CASES = {
    "focal known, true stature": (True, True, 0.0),
    "focal known, true stature, 2 px noise": (True, True, 2.0),
    f"focal known, stature {ADULT_STATURE_M:.2f} m": (True, False, 0.0),
    "focal unknown, true stature": (False, True, 0.0),
}
ERRORS = ("pitch_error_deg", "roll_error_deg", "height_error_pct", "focal_error_pct", "abs_mpjpe_mm", "mrpe_mm",
          "abs_mpjpe_true_camera_mm", "mrpe_true_camera_mm")


# Where the random evaluation cameras are: 1.5-4 m high, 4-10 m from the person along the floor, aimed at them
# (pitch 5-40 degrees, roll up to 5), a pinhole lens of 50-80 degrees with its principal point at the centre.
CAMERAS = CameraRanges(distance_m=(4.0, 10.0), pitch_deg=(5.0, 40.0), roll_deg=5.0, aspect_jitter=0.0,
                       principal_offset_px=0.0, image_size=IMAGE_SIZE, height_m=(1.5, 4.0), hfov_deg=(50.0, 80.0))


def walking_clips(motion: MotionSet, min_frames: int = 120) -> list[np.ndarray]:
    """The clips described as walking, centred in the floor plane, (T, 17, 3) each."""
    chosen = [i for i, text in enumerate(motion.clips["description"])
              if "walk" in str(text).lower() and motion.clip_lengths()[i] >= min_frames]
    return [centre_clip(motion.clip(i).astype(np.float64)) for i in chosen]


def stature(clip: np.ndarray) -> float:
    """The person's stature in the model of ``from_person``: the median head-joint height over the fraction."""
    return float(np.median(clip[:, H36M17.index("head"), 2]) / AXIS_HEIGHTS["head"])


def random_camera(clip: np.ndarray, rng: np.random.Generator, ranges: CameraRanges = CAMERAS,
                  attempts: int = 100) -> Camera | None:
    """A camera of the shared sampler (``sample_cameras``) aimed at the clip's mean pelvis that sees every joint
    of every frame, or None."""
    target = clip[:, 0].mean(axis=0, keepdims=True)
    for _ in range(attempts):
        camera = sample_cameras(target, rng, ranges).camera(0)
        if camera.sees(clip):
            return camera
    return None


def _scene(clips: list[np.ndarray], pair: int, people: int, rng: np.random.Generator) -> list[np.ndarray]:
    """``people`` walking clips for one pair, the first at the origin and the others moved up to 4 m away in
    the floor plan (people at different distances from the camera)."""
    chosen = [clips[(pair * people + k) % len(clips)] for k in range(people)]
    offsets = [np.zeros(3)] + [np.append(rng.uniform(-4.0, 4.0, 2), 0.0) for _ in range(people - 1)]
    return [clip + offset for clip, offset in zip(chosen, offsets)]


def run(motion: MotionSet, lifter, pairs: int = 12, seed: int = 0, bootstrap: int = 30,
        ranges: CameraRanges = CAMERAS, cases: dict = CASES, people: int = 1) -> list[dict]:
    """One row per (camera, clips, case) with the estimate, its standard deviations and errors; ``people``
    walking clips are seen at once by each camera and fitted jointly (the lifting errors average over them)."""
    rng = np.random.default_rng(seed)
    clips = walking_clips(motion)
    if not clips:
        raise ValueError("no walking clips (description containing 'walk', at least 120 frames) to evaluate on")
    rows = []
    for pair in range(pairs):
        scene = _scene(clips, pair, people, rng)
        camera = random_camera(np.concatenate(scene), rng, ranges)
        if camera is None:
            continue
        floor_camera = camera.in_floor_frame()
        truths = [floor_camera.camera_to_world(camera.world_to_camera(clip)) for clip in scene]
        cleans = [camera.project(clip) for clip in scene]
        true_lifts = [lifter.lift(clean, floor_camera).joints for clean in cleans]
        mean_stature = float(np.mean([stature(clip) for clip in scene]))
        for case, (focal_known, stature_known, noise_px) in cases.items():
            observed = [c + rng.normal(0.0, noise_px, c.shape) if noise_px else c for c in cleans]
            estimate = from_person(observed if people > 1 else observed[0], IMAGE_SIZE,
                                   mean_stature if stature_known else ADULT_STATURE_M,
                                   camera.K[0, 0] if focal_known else None, bootstrap=bootstrap, seed=pair)
            lifted = [lifter.lift(pixels, estimate.camera).joints for pixels in observed]
            references = ([lifter.lift(pixels, floor_camera).joints for pixels in observed] if noise_px
                          else true_lifts)

            def mean_error(metric, predictions):
                return 1e3 * float(np.mean([metric(p, t) for p, t in zip(predictions, truths)]))

            rows.append({
                "pair": pair, "case": case, "people": people, "frames": sum(len(c) for c in scene),
                "stature_m": mean_stature,
                "true_height_m": camera.camera_height, "true_pitch_deg": float(np.degrees(camera.pitch)),
                "true_roll_deg": float(np.degrees(camera.roll)), "true_focal_px": float(camera.K[0, 0]),
                **{f"estimated_{k}": v for k, v in estimate.to_dict().items() if k != "warnings"},
                "warnings": len(estimate.warnings),
                "pitch_error_deg": estimate.pitch_deg - float(np.degrees(camera.pitch)),
                "roll_error_deg": estimate.roll_deg - float(np.degrees(camera.roll)),
                "height_error_pct": 100 * (estimate.height_m / camera.camera_height - 1),
                "focal_error_pct": 100 * (estimate.focal_px / camera.K[0, 0] - 1),
                "abs_mpjpe_mm": mean_error(metrics.abs_mpjpe, lifted),
                "mrpe_mm": mean_error(metrics.mrpe, lifted),
                "abs_mpjpe_true_camera_mm": mean_error(metrics.abs_mpjpe, references),
                "mrpe_true_camera_mm": mean_error(metrics.mrpe, references),
            })
    return rows


def summarise(rows: list[dict]) -> dict:
    """Per case: median and 90th percentile of each absolute error, and how often the truth lies within two
    estimated standard deviations (pitch, height)."""
    summary = {}
    for case in dict.fromkeys(r["case"] for r in rows):
        chosen = [r for r in rows if r["case"] == case]
        entry = {"pairs": len(chosen)}
        for key in ERRORS:
            values = np.abs([r[key] for r in chosen])
            entry[key] = {"median": float(np.median(values)), "p90": float(np.percentile(values, 90))}
        entry["pitch_within_2sd"] = float(np.mean([abs(r["pitch_error_deg"]) <= 2 * r["estimated_pitch_sd_deg"]
                                                   for r in chosen]))
        entry["height_within_2sd"] = float(np.mean([
            abs(r["estimated_height_m"] - r["true_height_m"]) <= 2 * r["estimated_height_sd_m"] for r in chosen]))
        entry["warned"] = float(np.mean([r["warnings"] > 0 for r in chosen]))
        summary[case] = entry
    return summary


def write(rows: list[dict], out_dir: str | Path) -> list[Path]:
    """``calibration.csv`` (every row), ``calibration.json`` (the summary) and ``calibration.md`` (its table)."""
    out_dir = Path(out_dir)
    summary = summarise(rows)
    with atomic_path(out_dir / "calibration.csv", overwrite=True) as temporary, temporary.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with atomic_path(out_dir / "calibration.json", overwrite=True) as temporary:
        temporary.write_text(json.dumps(summary, indent=1))
    lines = ["| case | pairs | pitch err (deg) | roll err (deg) | height err (%) | focal err (%) | pitch / height "
             "within 2 sd | warned | Abs-MPJPE estimated / true camera (mm) | MRPE estimated / true camera (mm) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for case, s in summary.items():
        def cell(key: str) -> str:
            return f"{s[key]['median']:.2f} ({s[key]['p90']:.2f})"

        focal = cell("focal_error_pct") if not CASES.get(case, (True,))[0] else "given"
        lines.append(f"| {case} | {s['pairs']} | {cell('pitch_error_deg')} | {cell('roll_error_deg')} | "
                     f"{cell('height_error_pct')} | {focal} | {100 * s['pitch_within_2sd']:.0f}% / "
                     f"{100 * s['height_within_2sd']:.0f}% | {100 * s['warned']:.0f}% | "
                     f"{s['abs_mpjpe_mm']['median']:.0f} / "
                     f"{s['abs_mpjpe_true_camera_mm']['median']:.0f} | {s['mrpe_mm']['median']:.0f} / "
                     f"{s['mrpe_true_camera_mm']['median']:.0f} |")
    lines.append("\nErrors are absolute: median (90th percentile) over the (camera, clip) pairs; the last two columns "
                 "are medians.")
    with atomic_path(out_dir / "calibration.md", overwrite=True) as temporary:
        temporary.write_text("\n".join(lines) + "\n")
    return [out_dir / f"calibration.{suffix}" for suffix in ("csv", "json", "md")]
