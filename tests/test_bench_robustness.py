"""``ray3d bench robustness`` end to end on a tiny configuration; the sweep definitions match the grids."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from PIL import Image

from ray3d import cameras
from ray3d.bench.robustness import NOISE_LEVELS, perturbed
from ray3d.cli import main


def test_robustness_bench_writes_every_sweep(mocap_dir, tiny_checkpoint, tmp_path, capsys):
    out = tmp_path / "robustness"
    assert main(["bench", "robustness", "--out", str(out), "--models", f"tiny={tiny_checkpoint}", "rfrh",
                 "--clips", "2", "--frame-stride", "30", "--camera-stride", "10", "--data-dir", str(mocap_dir)]) == 0
    names = (["focal", "principal-point", "rotation", "pitch", "distance", "scale"]
             + [f"noise-{p}" for p in NOISE_LEVELS])
    for name in names:
        with (out / f"{name}.csv").open() as handle:
            rows = list(csv.DictReader(handle))
        assert {r["method"] for r in rows} == {"tiny", "rfrh"}
        assert all(np.isfinite(float(r["mrpe_mm"])) for r in rows)
        with Image.open(out / f"{name}.png") as image:
            assert image.format == "PNG"
        assert (out / f"{name}.md").read_text().startswith("|")
    scales = sorted({float(r["bone scale"]) for r in csv.DictReader((out / "scale.csv").open())})
    assert scales == [0.6, 0.7, 0.8, 0.9, 1.0, 1.1]
    assert "summary.md" in capsys.readouterr().out


@pytest.mark.parametrize("parameter", list(NOISE_LEVELS))
def test_perturbed_cameras_change_only_their_parameter(parameter):
    camera = cameras.h36m("S9", "54138969")
    same = perturbed(camera, parameter, 0.0, np.random.default_rng(0))
    np.testing.assert_allclose(same.R, camera.R, atol=1e-12)
    np.testing.assert_allclose(same.t, camera.t, atol=1e-12)
    np.testing.assert_allclose(same.K, camera.K, atol=1e-12)
    noisy = perturbed(camera, parameter, NOISE_LEVELS[parameter][1][-1], np.random.default_rng(0))
    if parameter in ("focal", "centre"):
        np.testing.assert_array_equal(noisy.R, camera.R)
        assert not np.allclose(noisy.K, camera.K)
    else:
        np.testing.assert_array_equal(noisy.K, camera.K)
        if parameter != "translation":
            np.testing.assert_allclose(noisy.center, camera.center, atol=1e-9)  # rotations keep the centre
        assert not np.allclose(noisy.R, camera.R) or parameter == "translation"
        if parameter == "yaw":  # a turn about the world vertical leaves the pitch alone
            assert noisy.pitch == pytest.approx(camera.pitch)
