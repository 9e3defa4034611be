"""``ray3d bench level``: people seen by low, nearly level cameras (the ``level-test`` set: 0.9-1.5 m high, 0-15
degrees down, 2.5-6 m away, landscape and portrait), through an emulated detector whose joints sit where real
detectors put them (``ray3d.data.samples.DETECTOR_JOINT_OFFSETS_M``, a share drawn per pair), people of statures
1.45-1.95 m, joints outside the picture unseen; each pair lifted as ``Lifter.lift`` lifts, refined and not, beside
the no-learning guess from the same detections (``ray3d.baselines.floor_guess``). Where a real low camera was worse than the guess (issue 45), this is the set that
shows it without the recording.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ray3d import metrics
from ray3d.baselines.floor_guess import floor_guess
from ray3d.bench.real_video import EMULATED_FPS, emulated_detections, emulated_layout
from ray3d.data.motion import MotionSet
from ray3d.data.samples import scale_bones
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.lifting.lifter import Lifter

BODY_SCALES = (0.86, 1.14)      # the performers' statures (1.6-1.75 m) scaled to 1.45-1.95 m
DETECTOR_OFFSET_SCALES = (0.5, 1.5)


def floor_errors(positions: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(T,) distances on the floor plan between (T, 3) positions and (T, 17, 3) true poses' pelvis (NaN stays)."""
    return np.linalg.norm(positions[:, :2] - truth[:, 0, :2], axis=-1)


def run(lifter: Lifter, motion: MotionSet, clips_per_camera: int = 1, seed: int = 0, max_frames: int = 300,
        cameras: list[Camera] | None = None) -> list[dict]:
    """One row per (camera, clip): network-only and refined errors, the guess's, and the stated uncertainty's
    coverage along the ray."""
    rng = np.random.default_rng(seed)
    layout = emulated_layout(lifter)
    step = int(round(60.0 / EMULATED_FPS))
    rows = []
    for k, camera in enumerate(cameras or grid("level-test")):
        for c in range(clips_per_camera):
            index = int(rng.integers(motion.num_clips))
            clip = centre_clip(motion.clip(index).astype(np.float64))[:2 * max_frames:step]
            clip = scale_bones(clip, np.full(clip.shape[:2], rng.uniform(*BODY_SCALES)))
            pixels = emulated_detections(clip, camera, rng, layout, rng.uniform(*DETECTOR_OFFSET_SCALES))
            distance = float(np.median(np.linalg.norm(clip[:, 0] - camera.center, axis=-1)))
            guess = floor_guess(pixels, camera, layout.name)
            row = {"camera": camera.name, "clip": str(motion.clips["clip_id"][index]),
                   "camera_height_m": camera.camera_height, "pitch_deg": float(np.degrees(camera.pitch)),
                   "distance_m": distance, "portrait": camera.image_size[1] > camera.image_size[0],
                   "guess_floor_error_m": float(np.nanmedian(floor_errors(guess, clip)))
                   if np.isfinite(guess).all(-1).any() else None}
            for refine in (False, True):
                try:
                    result = lifter.lift(pixels, camera, fps=EMULATED_FPS, layout=layout.name, refine=refine)
                except InputError as err:  # the root never in the picture
                    row["refused"] = err.message
                    break
                name = "refined" if refine else "network"
                in_sds = metrics.root_error_in_sds(result.joints, clip, result.position_sd, camera)
                predicted = np.linalg.norm(result.joints[:, 0] - camera.center, axis=-1)
                true = np.linalg.norm(clip[:, 0] - camera.center, axis=-1)
                placed = predicted > 0  # a network can put a person at the camera: no distance to compare
                predicted, true = predicted[placed], true[placed]
                row.update({f"{name}_mrpe_mm": 1e3 * float(metrics.mrpe(result.joints, clip)),
                            f"{name}_abs_mpjpe_mm": 1e3 * float(metrics.abs_mpjpe(result.joints, clip)),
                            f"{name}_floor_error_m": float(np.median(floor_errors(result.joints[:, 0], clip))),
                            f"{name}_distance_error": float(np.median(np.log(predicted / true))),
                            f"{name}_distance_error_frame_sd": float(np.std(np.log(predicted / true))),
                            f"{name}_predicted_distance_m": float(np.median(predicted)),
                            f"{name}_within_1sd": float(np.mean(in_sds[:, 0] <= 1)),
                            f"{name}_within_2sd": float(np.mean(in_sds[:, 0] <= 2))})
                if refine and result.refinement:
                    row["floor_cue_fraction"] = result.refinement["floor_cue_fraction"]
            rows.append(row)
    return rows


def summary(rows: list[dict]) -> dict:
    """Medians over the pairs lifted where the guess has an answer (the feet seen at least once), and the ratios
    to the guess's median floor error."""
    lifted = [r for r in rows if "refused" not in r and r["guess_floor_error_m"] is not None]
    if not lifted:
        raise InputError("bench level: no pair could be lifted")
    out = {"pairs": len(lifted), "refused": sum("refused" in r for r in rows),
           "feet_never_seen": sum("refused" not in r and r["guess_floor_error_m"] is None for r in rows),
           "guess_floor_error_m": float(np.median([r["guess_floor_error_m"] for r in lifted]))}
    for name in ("network", "refined"):
        for key in ("mrpe_mm", "abs_mpjpe_mm", "floor_error_m", "within_1sd", "within_2sd"):
            out[f"{name}_{key}"] = float(np.median([r[f"{name}_{key}"] for r in lifted]))
        out[f"{name}_distance_error_rms"] = float(np.sqrt(np.mean([r[f"{name}_distance_error"] ** 2 for r in lifted])))
        out[f"{name}_over_guess"] = out[f"{name}_floor_error_m"] / out["guess_floor_error_m"]
    return out


def write(out_dir: str | Path, rows: list[dict]) -> list[Path]:
    """``level.json`` (every row and the summary) and ``level.md`` (the summary as a table)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    totals = summary(rows)
    lines = ["| | floor error (median, m) | / the guess's | MRPE (mm) | Abs-MPJPE (mm) | within 1 sd | within 2 sd |",
             "|---|---|---|---|---|---|---|",
             f"| the guess | {totals['guess_floor_error_m']:.3f} | 1 | | | | |"]
    for name in ("network", "refined"):
        lines.append(f"| {name} | {totals[f'{name}_floor_error_m']:.3f} | {totals[f'{name}_over_guess']:.2f} | "
                     f"{totals[f'{name}_mrpe_mm']:.0f} | {totals[f'{name}_abs_mpjpe_mm']:.0f} | "
                     f"{100 * totals[f'{name}_within_1sd']:.0f} % | {100 * totals[f'{name}_within_2sd']:.0f} % |")
    lines.append(f"\n{totals['pairs']} pairs lifted beside the guess; {totals['feet_never_seen']} more had no guess (the "
                 f"feet never in the picture), {totals['refused']} could not be lifted.")
    files = [out_dir / "level.json", out_dir / "level.md"]
    for path, text in zip(files, (json.dumps({"summary": totals, "rows": rows}, indent=1), "\n".join(lines) + "\n")):
        with atomic_path(path, overwrite=True) as temporary:
            temporary.write_text(text)
    return files
