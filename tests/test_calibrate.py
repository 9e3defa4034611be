"""Floor-point calibration recovers a known camera; bad point files are refused clearly."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from ray3d import Camera, InputError
from ray3d.calibrate import from_floor_points, read_floor_points
from ray3d.cli import main
from ray3d.io.camera_files import load_cameras


def _truth() -> Camera:
    return Camera.from_height_pitch(2.7, 28.0, (1280, 720), roll_deg=1.5, focal_px=900.0)


def _floor(camera: Camera, noise_px: float = 0.0):
    xy = np.array([[3, -1.5], [3, 1.5], [7, -2.5], [7, 2.5], [5, 0.0], [4, 2.0]])
    pixels = camera.project(np.column_stack([xy, np.zeros(len(xy))]))
    return xy, pixels + np.random.default_rng(0).normal(0, noise_px, pixels.shape)


def test_recovers_the_pose_from_clean_floor_points():
    truth = _truth()
    camera, rms = from_floor_points(*_floor(truth), truth)
    assert rms < 1e-4
    np.testing.assert_allclose(camera.R, truth.R, atol=1e-6)
    np.testing.assert_allclose(camera.t, truth.t, atol=1e-6)


def test_noisy_points_still_give_height_and_pitch():
    truth = _truth()
    camera, rms = from_floor_points(*_floor(truth, noise_px=1.0), (900.0, 900.0, 640.0, 360.0), (1280, 720))
    assert rms < 2.0
    assert camera.camera_height == pytest.approx(truth.camera_height, abs=0.05)
    assert np.degrees(camera.pitch) == pytest.approx(28.0, abs=0.5)


def test_cli_writes_a_camera(tmp_path, capsys):
    xy, pixels = _floor(_truth())
    points = tmp_path / "floor.csv"
    with points.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["x", "y", "u", "v"])
        writer.writerows(np.column_stack([xy, pixels]).tolist())
    out = tmp_path / "camera.json"
    assert main(["calibrate", "--floor-points", str(points), "--focal", "900", "--image-size", "1280x720",
                 "--out", str(out)]) == 0
    assert "height 2.700 m, pitch 28.00 deg" in capsys.readouterr().out
    assert load_cameras(out)[0].camera_height == pytest.approx(2.7, abs=1e-6)


def test_bad_floor_point_files(tmp_path):
    few = tmp_path / "few.csv"
    few.write_text("x,y,u,v\n0,0,1,1\n1,0,2,1\n")
    with pytest.raises(InputError, match="2 floor point.*at least 4"):
        read_floor_points(few)
    missing = tmp_path / "missing.json"
    missing.write_text('[{"x": 1, "y": 2}]')
    with pytest.raises(InputError, match="needs x, y .* and u, v"):
        read_floor_points(missing)
