"""Several cameras, one world: the same person joined across cameras (also through a hand-over and a broken
track), two people crossing kept apart, joints fused nearer the truth than either camera's, clock offsets found,
a misplaced camera named, and the fused world file."""

from __future__ import annotations

import json

import numpy as np
import pytest
from browser import console_errors, needs_chromium, screenshot

from ray3d import InputError
from ray3d.data.virtual_cameras import mounted_camera
from ray3d.demo import demo_clip
from ray3d.fusion import find_time_offset, fuse_worlds
from ray3d.io.world import LiftResult, World, read_world, write_world

FPS = 10.0
CAMERAS = [mounted_camera(yaw, height, distance, None, f"cam{k}")
           for k, (yaw, height, distance) in enumerate([(0.0, 3.0, 6.0), (90.0, 2.5, 5.0), (200.0, 3.5, 7.0)])]


def _person(frames: int = 60, turn: float = 0.0, radius: float = 2.0, phase: float = 0.0) -> np.ndarray:
    """(frames, 17, 3) a person walking an arc of a circle about the room's centre (a path that curves: a clock
    offset cannot pass for a shift along it)."""
    pose = demo_clip()[0]
    pose = pose - pose[0] * [1, 1, 0]
    angle = phase + np.linspace(0.0, 1.6, frames) + turn
    path = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(frames)])
    return pose[None] + path[:, None]


def _seen(camera, truth: np.ndarray, frames: np.ndarray, bias_m: float = 0.0) -> LiftResult:
    """One camera's track of a person: the truth moved ``bias_m`` along the camera's ray (its depth error)."""
    joints = truth[frames]
    ray = joints[:, :1] - camera.center
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    sd = np.tile([0.12, 0.03], (len(frames), 1))
    return LiftResult(joints + bias_m * ray, np.zeros((len(frames), 17), bool), FPS, frames,
                      refinement={"stature_m": 1.7}, position_sd=sd)


def _world(camera, tracks: dict) -> World:
    return World(tracks, camera, "test")


def test_one_person_seen_by_two_cameras_is_one_track_nearer_the_truth_than_either():
    truth = _person()
    frames = np.arange(60)
    worlds = [_world(CAMERAS[0], {"7": _seen(CAMERAS[0], truth, frames, 0.25)}),
              _world(CAMERAS[1], {"3": _seen(CAMERAS[1], truth, frames, -0.25)})]
    fusion = fuse_worlds(worlds)
    assert list(fusion.members.values()) == [["cam0:7", "cam1:3"]]
    track = fusion.world.tracks["0"]
    assert track.seen_by.all() and track.seen_by.shape == (60, 2)
    fused = np.linalg.norm(track.joints[:, 0] - truth[:, 0], axis=-1).mean()
    single = [np.linalg.norm(w.tracks[n].root - truth[:, 0], axis=-1).mean() for w, n in zip(worlds, ("7", "3"))]
    assert fused < 0.3 * min(single)  # the rays cross at nearly a right angle: each one's depth error is undone
    assert track.refinement["stature_m"] == pytest.approx(1.7)


def test_a_hand_over_and_a_broken_track_keep_one_id_and_two_people_crossing_stay_apart():
    one, two = _person(turn=0.0), _person(turn=np.pi, radius=2.2)  # walking the same circle from opposite sides
    first, second = np.arange(0, 28), np.arange(33, 60)            # cam0 loses them both for half a second
    worlds = [_world(CAMERAS[0], {"a": _seen(CAMERAS[0], one, first), "b": _seen(CAMERAS[0], one, second),
                                  "c": _seen(CAMERAS[0], two, np.arange(60))}),
              # cam1 sees the first person only after they leave cam2's view: a hand-over 0.4 s later
              _world(CAMERAS[1], {"d": _seen(CAMERAS[1], one, np.arange(34, 60)),
                                  "e": _seen(CAMERAS[1], two, np.arange(60))}),
              _world(CAMERAS[2], {"f": _seen(CAMERAS[2], one, np.arange(0, 30))})]
    fusion = fuse_worlds(worlds)
    groups = sorted(sorted(m) for m in fusion.members.values())
    assert groups == [["cam0:a", "cam0:b", "cam1:d", "cam2:f"], ["cam0:c", "cam1:e"]]
    for track in fusion.world.tracks.values():
        truth = one if track.seen_by[:, 2].any() else two
        assert np.linalg.norm(track.joints[:, 0] - truth[track.frames, 0], axis=-1).max() < 0.05


def _offset_found(truth: np.ndarray, shift: int, biases_m: tuple[float, float]) -> tuple[float, float, World, World]:
    """The offset (frames) and its sd found between two cameras seeing ``truth``, each with its depth bias, the
    second camera's frames numbered ``shift`` later."""
    frames = np.arange(len(truth))
    reference = _world(CAMERAS[0], {"1": _seen(CAMERAS[0], truth, frames, biases_m[0])})
    late = _seen(CAMERAS[1], truth, frames, biases_m[1])
    other = _world(CAMERAS[1], {"1": LiftResult(late.joints, late.interpolated, FPS, frames + shift,
                                                position_sd=late.position_sd)})
    offset, sd = find_time_offset(reference, other)
    return offset * FPS, sd * FPS, reference, other


def test_a_clock_offset_is_found_within_a_frame_from_where_people_are_when_their_bodies_do_not_move():
    for shift in (-7, 0, 4):
        offset, sd, reference, other = _offset_found(_person(80), shift, (0.15, -0.2))
        assert abs(offset - shift) < 1.0 and 0.25 <= sd <= 2.0
        fusion = fuse_worlds([reference, other], find_offsets=True)
        assert len(fusion.world.tracks) == 1 and fusion.offsets_s[1] * FPS == pytest.approx(offset)


def test_a_clock_offset_is_found_to_a_fraction_of_a_frame_from_how_bodies_move_whatever_the_depth_biases():
    """A camera's depth bias passes for a time shift of a person walking along its ray; the body's motion about
    its root does not move with it."""
    clip = demo_clip()[::5]
    towards = -CAMERAS[0].center[:2] / np.linalg.norm(CAMERAS[0].center[:2])  # along the first camera's ray
    path = np.outer(np.arange(len(clip)) / FPS * 0.8 - 2.0, towards)
    truth = clip - clip[:, :1] * [1, 1, 0] + np.column_stack([path, np.zeros(len(clip))])[:, None]
    for shift in (-7, 3):
        offset, sd, _, _ = _offset_found(truth, shift, (0.3, 0.0))  # 0.3 m: 3.75 frames of the walk
        assert abs(offset - shift) < 0.5 and sd < 1.0


def _rig_with_one_camera_off(truth: np.ndarray, off: int, by_m: list[float]) -> list[World]:
    """Every camera seeing the person, camera ``off``'s file putting it ``by_m`` from where it hangs: everybody it
    sees lands that far off."""
    worlds = []
    for k, camera in enumerate(CAMERAS):
        seen = _seen(camera, truth, np.arange(len(truth)))
        if k == off:
            seen.joints = seen.joints + by_m
        worlds.append(_world(camera, {"1": seen}))
    return worlds


def test_a_camera_placed_half_a_metre_off_is_named():
    fusion = fuse_worlds(_rig_with_one_camera_off(_person(), 2, [0.5, 0.0, 0.0]))
    assert fusion.suspects() == ["cam2"]
    agree = {tuple(e["cameras"]): e["disagree"] for e in fusion.agreement}
    assert agree == {("cam0", "cam1"): False, ("cam0", "cam2"): True, ("cam1", "cam2"): True}


def test_a_camera_too_far_off_to_be_joined_is_named_and_two_walking_together_raise_no_alarm():
    truth = _person()
    frames = np.arange(60)
    fusion = fuse_worlds(_rig_with_one_camera_off(truth, 1, [0.0, 1.0, 0.0]))  # beyond the gate: not joined
    assert len(fusion.world.tracks) == 2 and fusion.suspects() == ["cam1"]
    beside = truth + [0.0, 0.0, 0.0] + 0.6 * np.array([np.cos(0.8), np.sin(0.8), 0.0])  # a second person, 0.6 m away
    together = [_world(c, {"a": _seen(c, truth, frames), "b": _seen(c, beside, frames)}) for c in CAMERAS[:2]]
    fusion = fuse_worlds(together)
    assert len(fusion.world.tracks) == 2 and fusion.suspects() == []
    assert all(not entry["disagree"] for entry in fusion.agreement)


def test_the_fused_world_file_says_which_cameras_saw_each_frame(tmp_path):
    from importlib import resources

    import jsonschema

    truth = _person()
    worlds = [_world(CAMERAS[0], {"1": _seen(CAMERAS[0], truth, np.arange(0, 40))}),
              _world(CAMERAS[1], {"1": _seen(CAMERAS[1], truth, np.arange(20, 60))})]
    fused = fuse_worlds(worlds).world
    path = write_world(tmp_path / "fused.json", fused)
    back = read_world(path)
    assert [c.name for c in back.cameras] == ["cam0", "cam1"]
    np.testing.assert_array_equal(back.tracks["0"].seen_by, fused.tracks["0"].seen_by)
    assert back.tracks["0"].seen_by[:20, 0].all() and not back.tracks["0"].seen_by[:20, 1].any()
    schema = json.loads(resources.files("ray3d").joinpath("assets", "world.schema.json").read_text())
    jsonschema.Draft202012Validator(schema).validate(json.loads(path.read_text()))
    with pytest.raises(InputError, match="several cameras .* is written as .json"):
        write_world(tmp_path / "fused.csv", fused)
    single = read_world(write_world(tmp_path / "one.json", worlds[0]))
    assert len(single.cameras) == 1 and single.tracks["1"].seen_by is None  # one camera: as before


def test_ray3d_fuse_writes_the_world_and_refuses_bad_input_in_one_line(tmp_path, capsys):
    from ray3d.cli import main

    truth = _person()
    paths = [str(write_world(tmp_path / f"w{k}.json", _world(c, {"1": _seen(c, truth, np.arange(60))})))
             for k, c in enumerate(CAMERAS[:2])]
    assert main(["fuse", *paths, "--out", str(tmp_path / "fused.json")]) == 0
    out = capsys.readouterr().out
    assert "person 0: cam0:1, cam1:1" in out and "1 people from 2 cameras" in out
    assert len(read_world(tmp_path / "fused.json").tracks) == 1
    site = tmp_path / "site.json"  # a site reads the fused world as it reads one camera's
    site.write_text(json.dumps({"lines": [{"name": "door", "start": [1.0, 0.5], "end": [1.0, 3.0]}]}))
    assert main(["site", str(tmp_path / "fused.json"), "--site", str(site), "--out", str(tmp_path / "report")]) == 0
    assert "line door: 0 forward, 1 back" in capsys.readouterr().out
    for arguments, message in ((paths[:1], "fusing needs two or more"),
                               ([*paths, "--offsets", "0,x"], "--offsets: expected seconds"),
                               ([*paths, "--offsets", "0"], "1 given for 2 cameras")):
        assert main(["fuse", *arguments, "--out", str(tmp_path / "again.json")]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1


@needs_chromium
def test_the_viewer_of_a_fused_world_draws_every_camera_in_headless_chromium(tmp_path, capsys):
    from ray3d.cli import main

    truth = _person()
    paths = [str(write_world(tmp_path / f"w{k}.json", _world(c, {"1": _seen(c, truth, np.arange(60))})))
             for k, c in enumerate(CAMERAS)]
    assert main(["fuse", *paths, "--out", str(tmp_path / "fused.json")]) == 0
    viewer = tmp_path / "viewer.html"
    assert main(["viz", str(tmp_path / "fused.json"), "--html", str(viewer)]) == 0
    capsys.readouterr()
    page = viewer.read_text()
    assert '"name": "cam1"' in page and '"name": "cam2"' in page
    assert console_errors(viewer) == "[]"
    assert main(["viz", paths[0], "--html", str(tmp_path / "one.html")]) == 0  # the same person, one camera
    shots = [screenshot(shown.as_uri() + "#view=top", tmp_path / f"{shown.stem}.png")[..., 0]
             for shown in (viewer, tmp_path / "one.html")]
    # The floor plan (top right) marks every camera: three black squares and their names, against one.
    dark = [(s[78:300, 765:995] < 60).sum() for s in shots]
    assert dark[0] > dark[1] + 60


def test_several_videos_need_one_camera_each_and_a_json_world(tmp_path, capsys):
    from ray3d.cli import main

    videos = [str(tmp_path / "a.mp4"), str(tmp_path / "b.mp4")]
    assert main(["video", *videos, "--camera", "h36m:S9:54138969", "--out", str(tmp_path / "out")]) == 2
    assert "--camera: 1 given for 2 videos" in capsys.readouterr().err
    assert main(["video", *videos, "--camera", "h36m:S9:54138969", "--camera", "h36m:S9:55011271", "--format",
                 ".csv", "--out", str(tmp_path / "out")]) == 2
    assert "fused into a .json world" in capsys.readouterr().err


def test_ray3d_lift_with_a_keypoint_file_per_camera_writes_one_fused_world(tmp_path, capsys):
    from ray3d.cli import main
    from ray3d.io.keypoints import Keypoints, write_keypoints_json

    truth = _person(40)
    arguments = []
    for k, camera in enumerate(CAMERAS[:2]):
        pixels = camera.project(truth)
        keypoints = Keypoints(pixels, np.ones(pixels.shape[:2]), np.arange(40), np.zeros(40, int), "h36m17", FPS,
                              "test")
        write_keypoints_json(tmp_path / f"k{k}.json", keypoints)
        (tmp_path / f"c{k}.json").write_text(json.dumps(camera.to_dict()))
        arguments += ["--keypoints", str(tmp_path / f"k{k}.json"), "--camera", str(tmp_path / f"c{k}.json")]
    assert main(["lift", *arguments, "--out", str(tmp_path / "fused.json")]) == 0
    assert "1 people from 2 cameras" in capsys.readouterr().out
    fused = read_world(tmp_path / "fused.json")
    assert len(fused.tracks) == 1 and fused.tracks["0"].seen_by.all() and len(fused.cameras) == 2
    assert np.median(np.linalg.norm(fused.tracks["0"].root[:, :2] - truth[:, 0, :2], axis=-1)) < 0.15
    assert main(["lift", *arguments[:4], "--keypoints", str(tmp_path / "k0.json"),
                 "--out", str(tmp_path / "again.json")]) == 2
    assert "--camera: 1 given for 2 keypoint files" in capsys.readouterr().err
    assert main(["lift", *arguments, "--out", str(tmp_path / "fused.csv")]) == 2
    assert "fused into a .json world" in capsys.readouterr().err
