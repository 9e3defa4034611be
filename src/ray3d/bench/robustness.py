"""Robustness sweeps of the paper's figures, on the test performers with GT 2D: focal length and principal
point (intrinsic-test), camera rotation, pitch and distance (extrinsic-test), body scale (scale-test), and
noisy camera parameters (the model is told a perturbed camera). Each sweep gives a CSV, a markdown table and a
PNG (MPJPE and MRPE against the swept variable, one line per method)."""

from __future__ import annotations

import csv
import dataclasses
from collections import defaultdict
from pathlib import Path

import numpy as np

from ray3d.checkpoints import RFRH, load_model
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import SCALE_TEST_FACTORS, grid
from ray3d.evaluate import evaluate
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path
from ray3d.viz.plots import plot_sweep_panels

# Calibration noise: parameter -> (unit, standard deviations); each level draws NOISE_DRAWS perturbed cameras.
NOISE_LEVELS = {
    "focal": ("%", (0.0, 1.0, 2.0, 5.0)),
    "centre": ("px", (0.0, 5.0, 10.0, 20.0)),
    "pitch": ("deg", (0.0, 0.5, 1.0, 2.0)),
    "yaw": ("deg", (0.0, 1.0, 2.0, 5.0)),
    "translation": ("m", (0.0, 0.05, 0.1, 0.2)),
}
NOISE_DRAWS = 3


@dataclasses.dataclass
class Sweep:
    name: str
    variable: str
    rows: list[dict]  # {"method", "x", "mpjpe_mm", "mrpe_mm", "frames"}


def perturbed(camera: Camera, parameter: str, sigma: float, rng: np.random.Generator) -> Camera:
    """``camera`` with Gaussian noise of ``sigma`` on one parameter (what a mis-calibration looks like)."""
    if parameter == "focal":
        scale = 1 + rng.normal(0, sigma / 100)
        K = camera.K * np.array([[scale, 1, 1], [1, scale, 1], [1, 1, 1]])
        return dataclasses.replace(camera, K=K)
    if parameter == "centre":
        K = camera.K.copy()
        K[:2, 2] += rng.normal(0, sigma, 2)
        return dataclasses.replace(camera, K=K)
    if parameter in ("pitch", "yaw"):
        angle = np.radians(rng.normal(0, sigma))
        if parameter == "pitch":  # tilt about the camera's own x axis
            c, s = np.cos(angle), np.sin(angle)
            R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ camera.R
        else:  # turn about the world's vertical axis through the camera
            c, s = np.cos(angle), np.sin(angle)
            R = camera.R @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
        return dataclasses.replace(camera, R=R, t=-R @ camera.center)
    if parameter == "translation":
        return dataclasses.replace(camera, t=camera.t - camera.R @ rng.normal(0, sigma, 3))
    raise ValueError(f"unknown camera parameter {parameter!r}")


def _rows(method: str, result: dict, key_of) -> list[dict]:
    """Per-camera results grouped by ``key_of(camera name, values)`` -> frame-weighted means."""
    groups: dict[float, list] = defaultdict(list)
    for name, values in result["per_camera"].items():
        key = key_of(name, values)
        if key is not None:
            groups[key].append(values)
    rows = []
    for x, parts in sorted(groups.items()):
        frames = sum(p["frames"] for p in parts)
        mean = {k: (sum(p[k] * p["frames"] for p in parts) / frames if parts[0][k] is not None else None)
                for k in ("mpjpe_mm", "mrpe_mm")}
        rows.append({"method": method, "x": x, **mean, "frames": frames})
    return rows


def run(models: list[str], motion: MotionSet, frame_stride: int = 4, camera_stride: int = 1,
        seed: int = 0) -> list[Sweep]:
    """Every sweep for every method: shipped model names, checkpoint paths, or ``rfrh``, each optionally
    labelled as ``LABEL=MODEL`` (the label names it in the tables and plots)."""
    sources = {m.partition("=")[0] if "=" in m else m: m.partition("=")[2] or m for m in models}
    networks = {label: (m if m == RFRH else load_model(m)[0]) for label, m in sources.items()}
    intrinsic = grid("intrinsic-test")[::camera_stride]
    extrinsic = grid("extrinsic-test")[::camera_stride]
    scale_cameras = grid("scale-test")
    sweeps = {name: Sweep(name, variable, []) for name, variable in (
        ("focal", "focal offset (px)"), ("principal-point", "principal point offset (px)"),
        ("rotation", "yaw (deg)"), ("pitch", "pitch (deg)"), ("distance", "distance (m)"), ("scale", "bone scale"))}
    for name, unit in ((p, u) for p, (u, _) in NOISE_LEVELS.items()):
        sweeps[f"noise-{name}"] = Sweep(f"noise-{name}", f"{name} noise sigma ({unit})", [])
    for method, network in networks.items():
        result = evaluate(network, motion, intrinsic, frame_stride=frame_stride)
        sweeps["focal"].rows += _rows(method, result, lambda n, v: float(n.split(":")[1][5:]))
        sweeps["principal-point"].rows += _rows(method, result, lambda n, v: float(n.split(":")[2][6:]))
        result = evaluate(network, motion, extrinsic, frame_stride=frame_stride)
        sweeps["rotation"].rows += _rows(method, result, lambda n, v: float(n.split(":")[1][3:])
                                         if n.startswith("rotation:") else None)
        sweeps["pitch"].rows += _rows(method, result, lambda n, v: round(v["pitch_deg"])
                                      if n.startswith(("pitch:", "rotation:")) else None)
        sweeps["distance"].rows += _rows(method, result, lambda n, v: float(n.split(":")[3][4:])
                                         if n.startswith("distance:") else None)
        for scale in sorted(SCALE_TEST_FACTORS + (1.0,)):
            result = evaluate(network, motion, scale_cameras, frame_stride=frame_stride, bone_scale=scale)
            sweeps["scale"].rows += _rows(method, result, lambda n, v, s=scale: s)
        for parameter, (_, sigmas) in NOISE_LEVELS.items():
            for sigma in sigmas:
                rng = np.random.default_rng(seed)
                true = [c for c in scale_cameras for _ in range(NOISE_DRAWS)]
                told = [perturbed(c, parameter, sigma, rng) for c in true]
                result = evaluate(network, motion, true, frame_stride=frame_stride, given_cameras=told)
                sweeps[f"noise-{parameter}"].rows += _rows(method, result, lambda n, v, s=sigma: s)
    return list(sweeps.values())


def write(sweeps: list[Sweep], out_dir: str | Path) -> list[Path]:
    """CSV, markdown and PNG per sweep into ``out_dir`` (replacing earlier runs' files)."""
    out_dir = Path(out_dir)
    written = []
    for sweep in sweeps:
        methods = list(dict.fromkeys(r["method"] for r in sweep.rows))
        xs = sorted({r["x"] for r in sweep.rows})
        value = {(r["method"], r["x"]): r for r in sweep.rows}
        with atomic_path(out_dir / f"{sweep.name}.csv",
                         overwrite=True) as temporary, temporary.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["method", sweep.variable, "mpjpe_mm", "mrpe_mm", "frames"])
            for r in sweep.rows:
                writer.writerow([r["method"], r["x"], r["mpjpe_mm"], r["mrpe_mm"], r["frames"]])
        lines = [f"| {sweep.variable} | " + " | ".join(f"{m} MPJPE / MRPE" for m in methods) + " |",
                 "|---" * (len(methods) + 1) + "|"]
        for x in xs:
            cells = []
            for m in methods:
                r = value.get((m, x))
                mpjpe = "-" if r is None or r["mpjpe_mm"] is None else f"{r['mpjpe_mm']:.1f}"
                cells.append(f"{mpjpe} / {r['mrpe_mm']:.1f}" if r else "-")
            lines.append(f"| {x:g} | " + " | ".join(cells) + " |")
        with atomic_path(out_dir / f"{sweep.name}.md", overwrite=True) as temporary:
            temporary.write_text("\n".join(lines) + "\n")
        panels = {label: {m: [value[(m, x)][metric] if (m, x) in value and value[(m, x)][metric] is not None
                              else np.nan for x in xs] for m in methods}
                  for metric, label in (("mpjpe_mm", "MPJPE (mm)"), ("mrpe_mm", "MRPE (mm)"))}
        plot_sweep_panels(xs, panels, sweep.variable, f"robustness: {sweep.name}", out_dir / f"{sweep.name}.png")
        written += [out_dir / f"{sweep.name}.{suffix}" for suffix in ("csv", "md", "png")]
    index = "\n".join(f"## {sweep.name}\n\n![{sweep.name}]({sweep.name}.png)\n\n"
                      f"{(out_dir / f'{sweep.name}.md').read_text()}"
                      for sweep in sweeps)
    with atomic_path(out_dir / "summary.md", overwrite=True) as temporary:
        temporary.write_text("# Robustness sweeps (test performers, GT 2D, mm)\n\n" + index)
    return written + [out_dir / "summary.md"]
