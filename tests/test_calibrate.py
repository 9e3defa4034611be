"""Floor-point calibration recovers a known camera; bad point files are refused clearly; a camera's floor is
settled from its lens's height or two cameras' triangulated ankles and written into its file."""

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


# --- a camera's floor settled for good (--floor-of) -------------------------------------------------------------


def test_the_lens_height_by_tape_puts_the_floor_of_a_frame_whose_z0_is_moved():
    from ray3d.calibrate import floor_from_lens_height

    camera = Camera.from_height_pitch(2.45, 20.0, (1280, 720), hfov_deg=70.0, name="door")
    assert floor_from_lens_height(camera, 2.45).floor_z_m == pytest.approx(0.0, abs=1e-9)
    board = floor_from_lens_height(camera.with_origin_at_height(0.75), 2.45)  # z = 0 on a table 0.75 m high
    assert board.floor_z_m == pytest.approx(-0.75, abs=1e-9) and board.how == "lens height" and board.sd_m > 0
    assert board.message("door") == "camera door's floor lies 0.75 +/- 0.02 m below its z = 0 (from its lens 2.45 m " \
                                    "over it, by tape)"
    for nonsense in (-2.45, 0.0, float("nan"), "2.45", True, 40.0):
        with pytest.raises(InputError) as refused:
            floor_from_lens_height(camera, nonsense)
        assert refused.value.arguments == ("lens_height_m",)


_FRONT = Camera.from_pose([0.0, 0.0, 1.2], 0.0, np.radians(8.0), 0.0, 640.0, 640.0, 640.0, 360.0, (1280, 720),
                          name="front")
_SIDE = Camera.from_pose([4.0, -4.5, 1.5], np.pi / 2, np.radians(10.0), 0.0, 640.0, 640.0, 640.0, 360.0,
                         (1280, 720), name="side")


def _walkers_seen_by(cameras: tuple[Camera, ...], count: int = 3, seed: int = 0) -> list[dict]:
    """``count`` walkers (the demo clip, adults' statures) 3.5-4.5 m before the front camera, seen at once by
    each of ``cameras`` through an emulated detector (COCO-17): each camera's {track: (frame ids, pixels)}."""
    from ray3d.bench.real_video import emulated_detections
    from ray3d.data.samples import scale_bones
    from ray3d.demo import demo_clip
    from ray3d.skeleton import layout_skeleton

    rng = np.random.default_rng(seed)
    clip = demo_clip()[:90:2].astype(np.float64)
    clip[..., :2] -= clip[:1, :1, :2]
    tracks = [{} for _ in cameras]
    for k in range(count):
        pose = scale_bones(clip, np.full(clip.shape[:2], rng.normal(1.0, 0.05)))
        pose = pose + [rng.uniform(3.5, 4.5), rng.uniform(-0.5, 0.5), 0.0]
        for seen, camera in zip(tracks, cameras):
            seen[k] = (np.arange(len(pose)) + 100, emulated_detections(pose, camera, rng, layout_skeleton("coco17"),
                                                                       1.0))
    return tracks


def test_two_cameras_seeing_the_same_walkers_find_the_floor_of_a_frame_whose_z0_is_moved():
    """The world's z = 0 put 0.10 m above the floor in both camera files: the walkers' ankles triangulated, less
    the detector's planted-ankle height, put the floor 0.10 m below it, within its sd."""
    from ray3d.calibrate import floor_from_cameras

    raised = (_FRONT.with_origin_at_height(0.10), _SIDE.with_origin_at_height(0.10))
    for seed in (0, 1):
        front, side = _walkers_seen_by((_FRONT, _SIDE), seed=seed)
        check = floor_from_cameras({"front": (front, raised[0]), "side": (side, raised[1])}, "coco17", 30.0)
        assert abs(check.floor_z_m + 0.10) < 0.03 and abs(check.floor_z_m + 0.10) < 2 * check.sd_m < 0.06
        assert check.how == "two cameras" and check.people == 3 and check.seconds > 3
        assert "below its z = 0 (from 3 people seen by both cameras over 4 s)" in check.message("front")


def test_two_cameras_that_never_see_one_person_at_once_are_refused_with_why():
    from ray3d.calibrate import floor_from_cameras

    front, side = _walkers_seen_by((_FRONT, _SIDE))
    later = {track: (frames + 10_000, pixels) for track, (frames, pixels) in side.items()}  # not one clock
    with pytest.raises(InputError, match="no person was seen by front and side at once: their frame ids never"):
        floor_from_cameras({"front": (front, _FRONT), "side": (later, _SIDE)}, "coco17", 30.0)
    # The side camera's file in another world frame (its origin 3 m off): the same moments, no rays that cross.
    elsewhere = Camera.from_pose([7.0, -4.5, 1.5], np.pi / 2, np.radians(10.0), 0.0, 640.0, 640.0, 640.0, 360.0,
                                 (1280, 720), name="side")
    with pytest.raises(InputError, match="share frame ids, but no two tracks' pelvis rays cross.*overlap"):
        floor_from_cameras({"front": (front, _FRONT), "side": (side, elsewhere)}, "coco17", 30.0)
    with pytest.raises(InputError, match="two cameras"):
        floor_from_cameras({"front": (front, _FRONT)}, "coco17", 30.0)


def _keypoint_file(path, tracks: dict):
    from ray3d.io.keypoints import Keypoints, write_keypoints_json

    rows = [(track, frame, pixels) for track, (frames, all_pixels) in tracks.items()
            for frame, pixels in zip(frames, all_pixels)]
    return write_keypoints_json(path, Keypoints(np.array([r[2] for r in rows]), None, np.array([r[1] for r in rows]),
                                                np.array([r[0] for r in rows]), "coco17", 30.0, "test"))


def test_calibrate_floor_of_writes_the_camera_file_with_its_floor_and_refuses_bad_input(tmp_path, capsys):
    from ray3d.io.camera_files import floor_z_of_camera_file, read_camera, read_floor, save_cameras

    front_file, side_file = tmp_path / "front.json", tmp_path / "side.json"
    stage = {"name": "stage", "polygon": [[2, 1], [6, 1], [6, 4], [2, 4]], "height_m": 0.6}
    front_file.write_text(json.dumps({**_FRONT.with_origin_at_height(0.10).to_dict(), "floor_regions": [stage],
                                      "description": "a board"}))
    save_cameras(side_file, [_SIDE.with_origin_at_height(0.10)])
    front, side = _walkers_seen_by((_FRONT, _SIDE))
    keypoints = _keypoint_file(tmp_path / "front-kps.json", front), _keypoint_file(tmp_path / "side-kps.json", side)
    out = tmp_path / "front-floor.json"
    two_cameras = ["calibrate", "--floor-of", str(front_file), "--keypoints", str(keypoints[0]), "--with-camera",
                   str(side_file), "--with-keypoints", str(keypoints[1]), "--out", str(out)]
    assert main(two_cameras) == 0
    said = capsys.readouterr().out
    assert said.startswith("camera front's floor lies 0.1") and "from 3 people seen by both cameras" in said
    assert said.strip().endswith(f"written to {out}: floor_z_m = -0.10")
    written = json.loads(out.read_text())
    assert abs(floor_z_of_camera_file(out) + 0.10) < 0.03 and written["description"] == "a board"
    assert written["floor_check"]["how"] == "two cameras" and written["floor_check"]["people"] == 3
    assert read_floor(out).regions[0].height_m == pytest.approx(0.6)
    np.testing.assert_allclose(read_camera(out).t, read_camera(front_file).t, atol=1e-12)
    # Written once: not again without --force, and never over an input.
    assert main(two_cameras) == 2 and "already exists" in capsys.readouterr().err
    assert main([*two_cameras, "--force"]) == 0
    capsys.readouterr()
    assert main([*two_cameras[:-1], str(front_file), "--force"]) == 2
    assert "is also an input" in capsys.readouterr().err and "floor_z_m" not in front_file.read_text()
    # By tape: a camera that is not ours (H3.6M's) is written in ours, its floor where the lens height puts it.
    tape = tmp_path / "h36m-floor.json"
    h36m = read_camera("h36m:S9:54138969")
    assert main(["calibrate", "--floor-of", "h36m:S9:54138969", "--lens-height", f"{h36m.center[2] + 0.05:.6f}",
                 "--out", str(tape)]) == 0
    assert "floor lies 0.05 +/- 0.02 m below its z = 0" in capsys.readouterr().out
    assert floor_z_of_camera_file(tape) == pytest.approx(-0.05, abs=1e-4)
    np.testing.assert_allclose(read_camera(tape).R, h36m.R, atol=1e-12)
    # Refused, one line naming the argument or the files, exit code 2, nothing written.
    refused = tmp_path / "refused.json"
    for arguments, why in (
            (["--lens-height", "-1.5"], "positive number of metres, got -1.5 (--lens-height)"),
            (["--lens-height", "40"], "more than 5 m"),
            ([], "pass --lens-height M, or --keypoints FILE"),
            (["--lens-height", "2", "--keypoints", str(keypoints[0])], "pass --lens-height M"),
            (["--keypoints", str(keypoints[0]), "--with-camera", str(side_file), "--with-keypoints",
              str(_keypoint_file(tmp_path / "later.json", {t: (f + 10_000, p) for t, (f, p) in side.items()}))],
             "frame ids never coincide")):
        assert main(["calibrate", "--floor-of", str(front_file), *arguments, "--out", str(refused)]) == 2
        err = capsys.readouterr().err
        assert why in err and len(err.strip().splitlines()) == 1, err
    assert not refused.exists()
