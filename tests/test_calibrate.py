"""Floor-point calibration recovers a known camera; bad point files are refused clearly."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from ray3d import Camera, InputError
from ray3d.calibrate import from_floor_points
from ray3d.cli import main
from ray3d.io.camera_files import load_cameras
from ray3d.io.floor_points import read_floor_points


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


# ---------------------------------------------------------------------------------------------- from a person
def _model_walker(stature: float = 1.75, frames: int = 120) -> np.ndarray:
    """(T, 17, 3) a person exactly as from_person models one: ankles, pelvis, thorax and head on a vertical
    line at AXIS_HEIGHTS, hips and shoulders beside it; walking towards the camera and across."""
    from ray3d.body import AXIS_HEIGHTS
    from ray3d.skeleton import H36M17

    t = np.linspace(0, 1, frames)
    path = np.column_stack([9 - 5 * t, 1.5 * np.sin(3 * t), np.zeros(frames)])
    body = np.zeros((17, 3))
    for joint, height in (("pelvis", "pelvis"), ("spine", "pelvis"), ("thorax", "thorax"), ("neck_nose", "thorax"),
                          ("head", "head"), ("l_ankle", "ankles"), ("r_ankle", "ankles")):
        body[H36M17.index(joint), 2] = AXIS_HEIGHTS[height] * stature
    for side, sign in (("l", 1), ("r", -1)):
        body[H36M17.index(f"{side}_ankle"), 1] = body[H36M17.index(f"{side}_hip"), 1] = 0.1 * sign
        body[H36M17.index(f"{side}_hip"), 2] = body[0, 2]
        for i, name in enumerate(("shoulder", "elbow", "wrist")):
            body[H36M17.index(f"{side}_{name}"), 1:] = [0.18 * sign, body[8, 2] - 0.3 * i]
        body[H36M17.index(f"{side}_knee"), 1:] = [0.1 * sign, 0.5]
    return body[None] + path[:, None]


def test_a_person_who_fits_the_model_gives_the_exact_camera():
    from ray3d.calibrate import MODEL_ERROR_SD, from_person

    truth = _truth()
    pixels = truth.project(_model_walker())
    known = from_person(pixels, truth.image_size, 1.75, focal_px=900.0, bootstrap=5)
    assert known.pitch_deg == pytest.approx(28.0, abs=0.05) and known.roll_deg == pytest.approx(1.5, abs=0.05)
    assert known.height_m == pytest.approx(2.7, rel=1e-3) and known.rms_px < 0.05
    np.testing.assert_allclose(known.camera.R, truth.R, atol=1e-3)
    unknown = from_person(pixels, truth.image_size, 1.75, bootstrap=5)
    assert unknown.focal_px == pytest.approx(900.0, rel=5e-3) and unknown.pitch_deg == pytest.approx(28.0, abs=0.1)
    # With 1 px of noise the estimate moves, and its bootstrap standard deviation says by about how much.
    noisy = from_person(pixels + np.random.default_rng(0).normal(0, 1.0, pixels.shape), truth.image_size, 1.75,
                        bootstrap=20, model_error=False)
    assert noisy.focal_sd_px > 0 and noisy.pitch_sd_deg > 0
    assert abs(noisy.focal_px - 900.0) < 4 * noisy.focal_sd_px + 1.0
    assert abs(noisy.pitch_deg - 28.0) < 4 * noisy.pitch_sd_deg + 0.05
    # Heights scale with the assumed stature, angles do not; the stature's uncertainty widens the height's.
    taller = from_person(pixels, truth.image_size, 1.75 * 1.1, focal_px=900.0, bootstrap=5, person_height_sd=0.0)
    assert taller.height_m == pytest.approx(1.1 * known.height_m, rel=1e-3)
    assert taller.pitch_deg == pytest.approx(known.pitch_deg, abs=1e-3)
    assert known.height_sd_m > taller.height_sd_m / 1.1
    # The standard deviations include the model error however well the frames agree.
    assert known.pitch_sd_deg == pytest.approx(MODEL_ERROR_SD["pitch_deg"], rel=1e-3)
    exact = from_person(pixels, truth.image_size, 1.75, focal_px=900.0, bootstrap=5, model_error=False,
                        person_height_sd=0.0)
    assert exact.pitch_sd_deg < 0.01 and exact.height_sd_m < 0.01


def test_several_people_are_fitted_jointly_and_their_errors_average_out():
    from ray3d.calibrate import MODEL_ERROR_SD, from_person

    truth = _truth()
    walkers = [_model_walker(frames=80) + [dx, dy, 0.0] for dx, dy in ((0, 0), (4, -1), (8, 1.5), (2, 2))]
    people = [truth.project(w) for w in walkers]
    alone = from_person(people[0], truth.image_size, 1.75, bootstrap=5)
    together = from_person(people, truth.image_size, 1.75, bootstrap=5)
    assert together.people == 4 and together.frames_used == 320 and not together.warnings
    assert together.focal_px == pytest.approx(900.0, rel=5e-3) and together.height_m == pytest.approx(2.7, rel=2e-3)
    # Four independent people: the model error and the stature's spread count half as much as for one.
    assert together.pitch_sd_deg == pytest.approx(MODEL_ERROR_SD["pitch_deg"] / 2, rel=0.05)
    assert together.height_sd_m < 0.6 * alone.height_sd_m
    confidences = [np.ones(p.shape[:2]) for p in people]
    confidences[1][:, :] = 0.0  # one person never seen: left out, the others still fit
    partly = from_person(people, truth.image_size, 1.75, focal_px=900.0, confidences=confidences, bootstrap=3)
    assert partly.people == 3 and partly.pitch_deg == pytest.approx(28.0, abs=0.05)
    with pytest.raises(InputError, match="2 arrays for 4 people"):
        from_person(people, truth.image_size, confidences=confidences[:2])


def test_a_poor_fit_warns_instead_of_looking_confident():
    from ray3d.calibrate import from_person

    truth = _truth()
    walker = _model_walker(frames=30)
    walker[:, :, 0] = walker[:1, :, 0]  # stands at one distance: the focal length cannot be told
    bent = _model_walker(frames=60)
    sway = 0.5 * (-1.0) ** np.arange(60)[:, None]  # head and thorax thrown from side to side every frame
    bent[:, [8, 9, 10], 1] += sway
    still = from_person(truth.project(walker), truth.image_size, 1.75, bootstrap=3)
    assert any("one distance" in w for w in still.warnings) and any("30 upright frames" in w for w in still.warnings)
    crooked = from_person(truth.project(bent), truth.image_size, 1.75, focal_px=900.0, bootstrap=3)
    assert crooked.rms_px > 5
    assert any("fits poorly" in w for w in crooked.warnings)
    assert not from_person(truth.project(_model_walker()), truth.image_size, 1.75, bootstrap=3).warnings


def test_a_walking_mocap_performer_gives_pitch_within_2_deg_and_height_within_10_percent(test_motion):
    from ray3d.bench.calibration import stature, walking_clips
    from ray3d.calibrate import from_person

    clip = walking_clips(test_motion)[0]
    # The camera looks along the direction the performer walks, so the distance to the camera changes.
    heading = clip[-1, 0, :2] - clip[0, 0, :2]
    yaw = float(np.arctan2(heading[1], heading[0]))
    centre = np.r_[clip[0, 0, :2] - 4.5 * np.array([np.cos(yaw), np.sin(yaw)]), 2.6]
    truth = Camera.from_pose(centre, yaw, np.radians(22.0), np.radians(2.0), 1000.0, 1000.0, 960.0, 540.0,
                             (1920, 1080))
    pixels = truth.project(clip)
    assert np.isfinite(pixels).all()
    result = from_person(pixels, truth.image_size, stature(clip), focal_px=1000.0, bootstrap=10)
    assert abs(result.pitch_deg - 22.0) < 2.0
    assert abs(result.height_m / 2.6 - 1) < 0.10
    assert result.pitch_sd_deg > 0 and result.height_sd_m > 0


def test_from_person_refuses_what_it_cannot_use():
    from ray3d.calibrate import from_person

    pixels = _truth().project(_model_walker(frames=30))
    with pytest.raises(InputError, match="at least 10"):
        from_person(pixels[:5], (1280, 720))
    hidden = pixels.copy()
    hidden[:25, 10] = np.nan  # the head of most frames
    with pytest.raises(InputError, match="5 frame"):
        from_person(hidden, (1280, 720))
    with pytest.raises(InputError, match=r"expected \(frames, 17, 2\)"):
        from_person(pixels[:, :16], (1280, 720))
    with pytest.raises(InputError, match="image_size"):
        from_person(pixels, (1280,))
    with pytest.raises(InputError, match="stature"):
        from_person(pixels, (1280, 720), person_height=170)


def test_calibrate_from_person_cli_writes_a_camera_with_its_uncertainty(tmp_path, capsys):
    truth = _truth()
    pixels = truth.project(_model_walker())
    keypoints = tmp_path / "walk.json"
    keypoints.write_text(json.dumps({"layout": "h36m17", "fps": 50, "detections": [
        {"frame": i, "keypoints": p.tolist()} for i, p in enumerate(pixels)]}))
    out = tmp_path / "camera.json"
    assert main(["calibrate", "--from-person", str(keypoints), "--image-size", "1280x720", "--focal", "900",
                 "--person-height", "1.75", "--out", str(out)]) == 0
    assert "pitch 28.0" in capsys.readouterr().out
    document = json.loads(out.read_text())
    assert document["pitch_deg"] == pytest.approx(28.0, abs=0.05) and "height_sd_m" in document
    camera = load_cameras(out)[0]
    assert camera.camera_height == pytest.approx(2.7, rel=1e-3)
    assert main(["calibrate", "--out", str(tmp_path / "x.json")]) == 2
    assert "exactly one of --floor-points" in capsys.readouterr().err
    assert main(["calibrate", "--from-person", str(keypoints), "--out", str(tmp_path / "y.json")]) == 2
    assert "--image-size" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists() and not (tmp_path / "y.json").exists()


def test_bench_calibration_writes_its_tables(test_motion, tmp_path):
    from ray3d.bench import calibration
    from ray3d.lifting.lifter import Lifter

    rows = calibration.run(test_motion, Lifter.load(), pairs=1, bootstrap=2,
                           cases={"focal known, true stature": (True, True, 0.0)})
    files = calibration.write(rows, tmp_path)
    assert [f.name for f in files] == ["calibration.csv", "calibration.json", "calibration.md"]
    summary = json.loads((tmp_path / "calibration.json").read_text())
    assert summary["focal known, true stature"]["pairs"] == 1
    for key in calibration.ERRORS:
        assert np.isfinite(summary["focal known, true stature"][key]["median"])
    assert "| focal known, true stature | 1 |" in (tmp_path / "calibration.md").read_text()


def test_bench_calibration_with_several_people_per_camera(test_motion, tmp_path, capsys):
    from ray3d.bench import calibration
    from ray3d.lifting.lifter import Lifter

    rows = calibration.run(test_motion, Lifter.load(), pairs=1, bootstrap=2, people=3,
                           cases={"focal known, true stature": (True, True, 0.0)})
    assert len(rows) == 1 and rows[0]["people"] == 3 and rows[0]["estimated_people"] == 3
    clips = calibration.walking_clips(test_motion)
    assert rows[0]["frames"] == sum(len(clips[k % len(clips)]) for k in range(3))
    assert abs(rows[0]["pitch_error_deg"]) < 5 and np.isfinite(rows[0]["mrpe_mm"])
    assert main(["bench", "calibration", "--out", str(tmp_path / "x"), "--people", "0"]) == 2
    assert "people must be at least 1, got 0 (--people)" in capsys.readouterr().err
