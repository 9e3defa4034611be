"""The main job: a bundled real motion clip of a test performer, seen by a real Human3.6M camera (lens
distortion included) that no model was trained on, lifted to world coordinates with the shipped weights and
compared with the truth and with the RFRH and VideoPose3D-style baselines; writes an HTML viewer and a GIF."""

from __future__ import annotations

import time
from importlib import resources
from pathlib import Path

import numpy as np

from ray3d import cameras, metrics
from ray3d.baselines.rfrh import rfrh_root
from ray3d.checkpoints import shipped_models
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import centre_clip
from ray3d.jobs import load_lifter
from ray3d.viz.animation import render_frames, save_animation
from ray3d.viz.html_viewer import write_viewer

DEMO_CLIP = "cmu_02_04.npz"
DEMO_CAMERA = ("S9", "54138969")


def demo_clip() -> np.ndarray:
    """(T, 17, 3) world joints of the bundled clip, centred in the floor plane."""
    with resources.as_file(resources.files("ray3d").joinpath("assets", "demo", DEMO_CLIP)) as path:
        return centre_clip(MotionSet.load(path).clip(0).astype(np.float64))


def run_demo(out_dir: str | Path = "ray3d-demo", checkpoint: str = "ray3d", baseline: str | None = "videopose3d",
             frames: int | None = None, gif_stride: int = 4) -> dict:
    """Run the demo; returns {"table": {method: errors in mm}, "viewer": path, "animation": path}."""
    started = time.perf_counter()
    out_dir = Path(out_dir)
    truth = demo_clip()[:frames]
    camera = cameras.h36m(*DEMO_CAMERA)
    assert camera.sees(truth), "the demo clip must be fully in view"
    pixels = camera.project(truth)

    def errors(predicted: np.ndarray) -> dict[str, float | None]:
        has_pose = not np.isnan(predicted[:, 1:]).all()
        return {"abs_mpjpe_mm": 1e3 * float(metrics.abs_mpjpe(predicted, truth)) if has_pose else None,
                "mrpe_mm": 1e3 * float(metrics.mrpe(predicted, truth)),
                "mpjpe_mm": 1e3 * float(metrics.mpjpe(predicted, truth)) if has_pose else None}

    lifter = load_lifter(checkpoint)
    predictions = {checkpoint: lifter.lift(pixels, camera).joints,
                   f"{checkpoint}, network only": lifter.lift(pixels, camera, refine=False).joints}
    if baseline and baseline in shipped_models():
        predictions[baseline] = load_lifter(baseline).lift(pixels, camera).joints
    rfrh = np.full_like(truth, np.nan)
    rfrh[:, 0] = rfrh_root(pixels[:, 0], camera)
    table = {name: errors(p) for name, p in {**predictions, "rfrh": rfrh}.items()}

    out_dir.mkdir(parents=True, exist_ok=True)
    viewer = write_viewer(out_dir / "viewer.html", {"truth": truth, **predictions}, fps=60.0, camera=camera,
                          title="ray3d demo: CMU 02_04 (jump, balance) seen by Human3.6M camera S9/54138969",
                          overwrite=True)
    images = render_frames({checkpoint: predictions[checkpoint]}, camera, {checkpoint: pixels}, truth,
                           stride=gif_stride, fps=60.0)
    animation = save_animation(images, out_dir / "demo.gif", fps=60.0 / gif_stride, overwrite=True)
    return {"table": table, "viewer": viewer, "animation": animation, "frames": len(truth), "camera": camera.name,
            "seconds": time.perf_counter() - started}


def format_report(result: dict) -> str:
    lines = [f"ray3d demo: bundled clip CMU 02_04 (a test performer, {result['frames']} frames at 60 fps) seen by "
             f"{result['camera']} (real calibration, lens distortion; never used in training), ground-truth 2D",
             f"{'method':<24}{'Abs-MPJPE':>11}{'MRPE':>9}{'MPJPE':>9}   (mm, world frame)"]
    for name, values in result["table"].items():
        cells = "".join(f"{values[k]:>{w}.1f}" if values[k] is not None else f"{'-':>{w}}"
                        for k, w in (("abs_mpjpe_mm", 11), ("mrpe_mm", 9), ("mpjpe_mm", 9)))
        lines.append(f"{name:<24}{cells}")
    lines.append(f"viewer: {result['viewer']}   animation: {result['animation']}   ({result['seconds']:.1f} s)")
    return "\n".join(lines)
