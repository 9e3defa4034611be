"""``ray3d bench level``: people seen by low, nearly level cameras (the ``level-test`` set: 0.9-1.5 m high, 0-15
degrees down, 2.5-6 m away, landscape and portrait), through an emulated detector whose joints sit where real
detectors put them (``ray3d.data.samples.DETECTOR_JOINT_OFFSETS_M``, a share drawn per pair), people of statures
1.45-1.95 m, joints outside the picture unseen; each pair lifted as ``Lifter.lift`` lifts, refined and not, beside
the no-learning guess from the same detections (``ray3d.baselines.floor_guess``). Where a real low camera was worse than
the guess (issue 45), this is the set that shows it without the recording.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d import body, metrics
from ray3d.baselines.floor_guess import floor_guess
from ray3d.bench.real_video import EMULATED_FPS, emulated_detections, emulated_layout
from ray3d.data.motion import MotionSet
from ray3d.data.samples import scale_bones
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.lifting.lifter import Lifter
from ray3d.refine import RefineConfig

BODY_SCALES = (0.86, 1.14)      # the performers' statures (1.6-1.75 m) scaled to 1.45-1.95 m
DETECTOR_OFFSET_SCALES = (0.5, 1.5)


def floor_errors(positions: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(T,) distances on the floor plan between (T, 3) positions and (T, 17, 3) true poses' pelvis (NaN stays)."""
    return np.linalg.norm(positions[:, :2] - truth[:, 0, :2], axis=-1)


def run(lifter: Lifter, motion: MotionSet, clips_per_camera: int = 1, seed: int = 0, max_frames: int = 300,
        cameras: list[Camera] | None = None, floor_offset_m: float = 0.0, floor_z: float | None = None,
        population_scale: float = 1.0) -> list[dict]:
    """One row per (camera, clip): network-only and refined errors, the guess's, and the stated uncertainty's
    coverage along the ray and across it. A camera's ``clips_per_camera`` people are lifted together, as a
    site's camera sees them (``Lifter.lift_tracks``: what they share, the ankle plane, is observed from all).
    ``floor_offset_m``: the camera given to the lifter and the guess has its z = 0 this far above the floor
    (a calibration board on a table: ``Camera.with_origin_at_height``); the detections are the true camera's.
    ``floor_z``: where the lifter is told the floor is in the given camera's frame (None: observed; 0: the
    camera's z = 0 assumed to be the floor, as ray3d did before it observed it). ``population_scale``: every
    person's size times this (1.04: a population 4 % taller than the prior's, which the people's sizes cannot
    tell from a floor lower than it is). The lifter knows the keypoints for an emulated detector's
    (``body.EMULATED_DETECTOR``: its planted ankles and size chain), as it knows a real detector's."""
    if not np.isfinite(population_scale) or not 0.5 <= population_scale <= 2.0:
        raise InputError(f"population_scale: a factor of people's sizes within 0.5-2; got {population_scale}",
                         ("population_scale",))
    rng = np.random.default_rng(seed)
    layout = emulated_layout(lifter)
    step = int(round(60.0 / EMULATED_FPS))
    rows = []
    for camera in cameras or grid("level-test"):
        given = camera.with_origin_at_height(floor_offset_m)
        people = {}
        for c in range(clips_per_camera):
            index = int(rng.integers(motion.num_clips))
            clip = centre_clip(motion.clip(index).astype(np.float64))[:2 * max_frames:step]
            clip = scale_bones(clip, np.full(clip.shape[:2], population_scale * rng.uniform(*BODY_SCALES)))
            pixels = emulated_detections(clip, camera, rng, layout, rng.uniform(*DETECTOR_OFFSET_SCALES))
            clip = clip - [0.0, 0.0, floor_offset_m]  # the truth in the given camera's frame
            guess = floor_guess(pixels, given, layout.name)
            people[c] = (clip, pixels, {
                "camera": camera.name, "clip": str(motion.clips["clip_id"][index]), "floor_offset_m": floor_offset_m,
                "population_scale": population_scale,
                "people_on_camera": clips_per_camera, "camera_height_m": camera.camera_height,
                "pitch_deg": float(np.degrees(camera.pitch)),
                "distance_m": float(np.median(np.linalg.norm(clip[:, 0] - given.center, axis=-1))),
                "portrait": camera.image_size[1] > camera.image_size[0],
                "guess_floor_error_m": float(np.nanmedian(floor_errors(guess, clip)))
                if np.isfinite(guess).all(-1).any() else None})
        tracks = {c: (np.arange(len(pixels)), pixels) for c, (_, pixels, _) in people.items()}
        for refine in (False, True):
            lifted = _lift_people(lifter, tracks, given, layout.name, refine, floor_z)
            for c, (clip, _, row) in people.items():
                if isinstance(lifted, str) or c not in lifted:
                    row["refused"] = lifted if isinstance(lifted, str) else lifted.unliftable[c]
                    continue
                row.update(_scores("refined" if refine else "network", lifted[c], clip, given))
                if refine:
                    plane = lifted.ankle_plane
                    row.update({"floor_cue_fraction": lifted[c].refinement["floor_cue_fraction"],
                                "ankle_plane_m": plane.height_m, "ankle_plane_sd_m": plane.sd_m,
                                "ankle_plane_people": plane.people, "ankle_plane_decision": plane.decision,
                                "ankle_plane_chance_off": plane.chance_off,
                                "ankle_plane_observed_m": plane.observed_m,
                                "ankle_plane_observed_sd_m": plane.observed_sd_m})
        rows += [row for _, _, row in people.values()]
    return rows


def _lift_people(lifter: Lifter, tracks: dict, camera: Camera, layout: str, refine: bool, floor_z: float | None):
    """The tracks lifted together, or why none could be (the root never in the picture)."""
    config = RefineConfig.for_model(lifter.document, layout, source=body.EMULATED_DETECTOR) if refine else False
    try:
        return lifter.lift_tracks(tracks, camera, layout, EMULATED_FPS, refine=config, floor_z=floor_z)
    except InputError as err:
        return err.message


def _scores(name: str, result, clip: np.ndarray, camera: Camera) -> dict:
    """One lifted person's errors against the truth, and how often the truth lies within the stated sds."""
    in_sds = metrics.root_error_in_sds(result.joints, clip, result.position_sd, camera)
    predicted = np.linalg.norm(result.joints[:, 0] - camera.center, axis=-1)
    true = np.linalg.norm(clip[:, 0] - camera.center, axis=-1)
    placed = predicted > 0  # a network can put a person at the camera: no distance to compare
    predicted, true = predicted[placed], true[placed]
    return {f"{name}_mrpe_mm": 1e3 * float(metrics.mrpe(result.joints, clip)),
            f"{name}_abs_mpjpe_mm": 1e3 * float(metrics.abs_mpjpe(result.joints, clip)),
            f"{name}_floor_error_m": float(np.median(floor_errors(result.joints[:, 0], clip))),
            f"{name}_distance_error": float(np.median(np.log(predicted / true))),
            f"{name}_distance_error_frame_sd": float(np.std(np.log(predicted / true))),
            f"{name}_predicted_distance_m": float(np.median(predicted)),
            f"{name}_within_1sd": float(np.mean(in_sds[:, 0] <= 1)),
            f"{name}_within_2sd": float(np.mean(in_sds[:, 0] <= 2)),
            f"{name}_across_within_1sd": float(np.mean(in_sds[:, 1] <= 1)),
            f"{name}_across_within_2sd": float(np.mean(in_sds[:, 1] <= 2))}


def summary(rows: list[dict]) -> dict:
    """Medians over the pairs lifted where the guess has an answer (the feet seen at least once), and the ratios
    to the guess's median floor error."""
    lifted = [r for r in rows if "refused" not in r and r["guess_floor_error_m"] is not None]
    if not lifted:
        raise InputError("bench level: no pair could be lifted")
    planes = [r["ankle_plane_m"] + r["floor_offset_m"] for r in lifted if "ankle_plane_m" in r]
    out = {"pairs": len(lifted), "refused": sum("refused" in r for r in rows),
           "floor_offset_m": lifted[0]["floor_offset_m"], "people_per_camera": lifted[0]["people_on_camera"],
           "population_scale": lifted[0].get("population_scale", 1.0),
           "floor_applied_share": float(np.mean([r["ankle_plane_decision"] == "applied" for r in lifted
                                                 if "ankle_plane_decision" in r])) if planes else None,
           "ankle_plane_over_floor_m": float(np.median(planes)) if planes else None,
           "feet_never_seen": sum("refused" not in r and r["guess_floor_error_m"] is None for r in rows),
           "guess_floor_error_m": float(np.median([r["guess_floor_error_m"] for r in lifted]))}
    for name in ("network", "refined"):
        for key in ("mrpe_mm", "abs_mpjpe_mm", "floor_error_m", "within_1sd", "within_2sd", "across_within_1sd",
                    "across_within_2sd"):
            out[f"{name}_{key}"] = float(np.median([r[f"{name}_{key}"] for r in lifted]))
        out[f"{name}_distance_error_rms"] = float(np.sqrt(np.mean([r[f"{name}_distance_error"] ** 2 for r in lifted])))
        out[f"{name}_over_guess"] = out[f"{name}_floor_error_m"] / out["guess_floor_error_m"]
    return out


def write(out_dir: str | Path, rows: list[dict]) -> list[Path]:
    """``level.json`` (every row and the summary) and ``level.md`` (the summary as a table)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    totals = summary(rows)
    lines = [f"The camera's z = 0 {totals['floor_offset_m']:+.2f} m off the floor, {totals['people_per_camera']} "
             "people per camera lifted together, people's sizes x "
             f"{totals['population_scale']:.2f}.\n",
             "| | floor error (median, m) | / the guess's | MRPE (mm) | Abs-MPJPE (mm) | within 1 sd | within 2 sd "
             "| across: within 1 sd | within 2 sd |",
             "|---|---|---|---|---|---|---|---|---|",
             f"| the guess | {totals['guess_floor_error_m']:.3f} | 1 | | | | | | |"]
    for name in ("network", "refined"):
        lines.append(f"| {name} | {totals[f'{name}_floor_error_m']:.3f} | {totals[f'{name}_over_guess']:.2f} | "
                     f"{totals[f'{name}_mrpe_mm']:.0f} | {totals[f'{name}_abs_mpjpe_mm']:.0f} | "
                     f"{100 * totals[f'{name}_within_1sd']:.0f} % | {100 * totals[f'{name}_within_2sd']:.0f} % | "
                     f"{100 * totals[f'{name}_across_within_1sd']:.0f} % | "
                     f"{100 * totals[f'{name}_across_within_2sd']:.0f} % |")
    lines.append(f"\n{totals['pairs']} pairs lifted beside the guess; {totals['feet_never_seen']} more had no guess "
                 f"(the feet never in the picture), {totals['refused']} could not be lifted."
                 + ("" if totals["ankle_plane_over_floor_m"] is None else
                    f" The ankle plane used: {totals['ankle_plane_over_floor_m']:.3f} m over the floor (median); the "
                    f"people's floor applied for {100 * totals['floor_applied_share']:.0f} % of the pairs."))
    files = [out_dir / "level.json", out_dir / "level.md"]
    for path, text in zip(files, (json.dumps({"summary": totals, "rows": rows}, indent=1), "\n".join(lines) + "\n")):
        with atomic_path(path, overwrite=True) as temporary:
            temporary.write_text(text)
    return files
