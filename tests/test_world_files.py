"""The lifted result and its world files: every format reads back what it wrote, several tracks included."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.io.world import FORMATS, LiftResult, World, read_world, write_world

CAMERA = cameras.h36m("S9", "54138969")


def _world(rng) -> World:
    def track(frames, first):
        joints = rng.normal(0, 0.3, (frames, 17, 3)) + [2.0, 1.0, 1.0]
        interpolated = rng.random((frames, 17)) < 0.1
        return LiftResult(joints, interpolated, 30.0, np.arange(first, first + frames),
                          position_sd=rng.uniform(0.01, 0.5, (frames, 2)))

    return World({"7": track(5, 10), "person b": track(3, 0)}, CAMERA, "ray3d")


@pytest.mark.parametrize("suffix", FORMATS)
def test_every_format_reads_back_what_it_wrote(tmp_path, rng, suffix):
    world = _world(rng)
    path = write_world(tmp_path / f"world{suffix}", world)
    back = read_world(path)
    assert list(back.tracks) == ["7", "person b"] and back.model == "ray3d" and back.fps == 30.0
    assert back.camera.name == world.camera.name and back.path == path
    np.testing.assert_allclose(back.camera.R, world.camera.R, atol=1e-12)
    for name, result in world.tracks.items():
        np.testing.assert_allclose(back.tracks[name].joints, result.joints, atol=1e-5)
        np.testing.assert_array_equal(back.tracks[name].interpolated, result.interpolated)
        np.testing.assert_array_equal(back.tracks[name].frames, result.frames)
        np.testing.assert_array_equal(back.tracks[name].root, back.tracks[name].joints[:, 0])
        np.testing.assert_allclose(back.tracks[name].position_sd, result.position_sd, atol=1e-4)
    assert back.track().frames[0] == 10 and len(back.track("person b").joints) == 3


def test_a_missing_track_and_a_foreign_file_are_refused(tmp_path, rng):
    path = write_world(tmp_path / "w.json", _world(rng))
    with pytest.raises(InputError, match=r"w.json: no track 'x'; tracks: 7, person b"):
        read_world(path).track("x")
    (tmp_path / "other.json").write_text('{"tracks": 3}')
    with pytest.raises(InputError, match="not a world file"):
        read_world(tmp_path / "other.json")
    with pytest.raises(InputError, match="unknown world file format"):
        write_world(tmp_path / "w.txt", _world(rng))
    with pytest.raises(InputError, match="already exists"):
        write_world(path, _world(rng))


def test_a_csv_written_before_the_refinement_still_reads(tmp_path, rng):
    world = _world(rng)
    path = write_world(tmp_path / "new.csv", world)
    lines = path.read_text().splitlines()
    old = [lines[0], "frame,track,joint,x,y,z"] + [",".join(line.split(",")[:6]) for line in lines[3:]]
    (tmp_path / "old.csv").write_text("\n".join(old) + "\n")
    back = read_world(tmp_path / "old.csv")
    np.testing.assert_allclose(back.track("7").joints, world.tracks["7"].joints, atol=1e-5)
    assert not back.track("7").interpolated.any() and back.track("7").refinement is None
    assert back.track("7").position_sd is None


@pytest.mark.parametrize("suffix", FORMATS)
def test_a_track_without_an_uncertainty_reads_back_without_one(tmp_path, rng, suffix):
    world = _world(rng)
    world.tracks["7"].position_sd = None
    back = read_world(write_world(tmp_path / f"w{suffix}", world))
    assert back.track("7").position_sd is None and back.track("person b").position_sd.shape == (3, 2)


def test_trc_export_has_opensims_header_and_markers_in_millimetres_y_up(tmp_path):
    """Two tracks, the second starting later: every joint a marker (TRACK_joint), one row per frame of either,
    blank where a track has no frame; millimetres; OpenSim's y up."""
    joints = np.zeros((3, 17, 3))
    joints[:, 0] = [[1.0, 2.0, 0.9], [1.1, 2.0, 0.9], [1.2, 2.0, 0.9]]
    world = World({"0": LiftResult(joints, np.zeros((3, 17), bool), 25.0, np.arange(3)),
                   "4": LiftResult(joints + 1.0, np.zeros((3, 17), bool), 25.0, np.arange(2, 5))},
                  cameras.h36m("S9", "54138969"), "test")
    path = write_world(tmp_path / "people.trc", world)
    lines = path.read_text().split("\n")
    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", "people.trc"]
    assert lines[1].split("\t")[:5] == ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units"]
    rate, camera_rate, frames, markers, units, *_ = lines[2].split("\t")
    assert (float(rate), float(camera_rate), int(frames), int(markers), units) == (25.0, 25.0, 5, 34, "mm")
    names = [n for n in lines[3].split("\t")[2:] if n]
    assert names[:2] == ["0_pelvis", "0_r_hip"] and names[17] == "4_pelvis" and len(names) == 34
    assert lines[4].split("\t")[2:5] == ["X1", "Y1", "Z1"] and lines[5] == ""
    first = lines[6].split("\t")
    assert first[:2] == ["1", "0.00000"]
    np.testing.assert_allclose([float(v) for v in first[2:5]], [1000.0, 900.0, -2000.0])  # (x, z, -y) in mm
    assert first[2 + 17 * 3] == ""  # track 4 has no frame 0
    last = lines[10].split("\t")
    assert last[:2] == ["5", "0.16000"] and last[2] == "" and float(last[2 + 17 * 3]) == pytest.approx(2200.0)
    with pytest.raises(InputError, match="unknown world file format .trc"):  # an export, not read back
        read_world(path)


def _animated_skeleton(rng, frames=40, stretch=0.0):
    """(T, 17, 3) H36M-17 joints of a random body turning at every joint while walking, each bone's length
    changing by up to ``stretch`` metres from frame to frame."""
    from scipy.spatial.transform import Rotation

    from ray3d.skeleton import H36M17
    rest = rng.normal(0, 0.2, (17, 3))
    joints = np.zeros((frames, 17, 3))
    turns = np.zeros((frames, 17, 3, 3))
    for j, parent in enumerate(H36M17.parents):
        local = Rotation.from_rotvec(rng.normal(0, 0.6, (frames, 3)) * np.linspace(0, 1, frames)[:, None]).as_matrix()
        if parent < 0:
            turns[:, j] = local
            joints[:, j] = np.array([0.0, 0.0, 0.9]) + np.linspace(0, 2, frames)[:, None] * [1.0, 0.5, 0.0]
        else:
            turns[:, j] = turns[:, parent] @ local
            bone = (rest[j] - rest[parent]) * (1 + stretch * rng.uniform(-1, 1, (frames, 1)))
            joints[:, j] = joints[:, parent] + np.einsum("tij,tj->ti", turns[:, parent], bone)
    return joints


def _bvh_joints(path):
    from ray3d.data.bvh import read_bvh
    from ray3d.io.bvh_export import Y_UP
    from ray3d.skeleton import H36M17
    motion = read_bvh(path)
    return motion.positions()[:, [motion.tree.names.index(n) for n in H36M17.joint_names]] @ Y_UP, motion


@pytest.mark.parametrize("stretch", [0.0, 0.2])
def test_bvh_export_reads_back_through_our_importer(tmp_path, rng, stretch):
    from ray3d.io.bvh_export import bvh_text
    from ray3d.skeleton import H36M17
    joints = _animated_skeleton(rng, stretch=stretch)
    world = World({"walker": LiftResult(joints, np.zeros((40, 17), bool), 25.0, np.arange(40))}, CAMERA, "test")
    back, motion = _bvh_joints(write_world(tmp_path / "walk.bvh", world))
    np.testing.assert_allclose(back, joints, atol=1e-5)  # every joint's offset travels: exact at any stretch
    assert motion.fps == pytest.approx(25.0, rel=1e-8) and len(motion.motion) == 40
    rigid = tmp_path / "rigid.bvh"
    rigid.write_text(bvh_text(joints, H36M17, 25.0, rigid=True))
    back, motion = _bvh_joints(rigid)
    assert sum(len(c) for c in motion.channels) == 6 + 3 * 16  # rotations only below the root
    error = np.linalg.norm(back - joints, axis=-1).max()
    assert error < 1e-5 if stretch == 0 else 1e-3 < error  # fixed bones follow rigid motion only
    np.testing.assert_allclose(back[:, 0], joints[:, 0], atol=1e-6)  # the root's path, in metres


def test_bvh_rest_pose_is_a_t_pose_facing_z_with_median_bones(tmp_path, rng):
    from ray3d.skeleton import H36M17
    joints = _animated_skeleton(rng, stretch=0.1)
    world = World({"0": LiftResult(joints, np.zeros((40, 17), bool), 30.0, np.arange(40))}, CAMERA, "test")
    _, motion = _bvh_joints(write_world(tmp_path / "a.bvh", world))
    offsets = dict(zip(motion.tree.names, motion.tree.offsets))
    lengths = np.median(np.linalg.norm(joints[:, 1:] - joints[:, list(H36M17.parents[1:])], axis=-1), axis=0)
    for name in ("l_knee", "r_ankle"):
        assert offsets[name][1] < 0 and np.allclose(offsets[name][[0, 2]], 0)  # legs straight down
    assert offsets["l_elbow"][0] > 0 > offsets["r_elbow"][0]  # left along +x, arms out sideways
    for name in ("thorax", "head"):  # a chain of one bone each above the spine: straight up
        assert offsets[name][1] > 0 and np.allclose(offsets[name][[0, 2]], 0)
    np.testing.assert_allclose([np.linalg.norm(offsets[n]) for n in H36M17.joint_names[1:]], lengths, atol=2e-6)


def test_bvh_of_several_tracks_writes_one_file_each_and_refuses_what_it_cannot_hold(tmp_path, rng):
    from ray3d.io.bvh_export import export_paths
    joints = _animated_skeleton(rng)
    tracks = {str(t): LiftResult(joints + t, np.zeros((40, 17), bool), 30.0, np.arange(40) + 10 * t) for t in (3, 8)}
    world = World(tracks, CAMERA, "test")
    write_world(tmp_path / "people.bvh", world)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["people_3.bvh", "people_8.bvh"]
    assert export_paths(tmp_path / "people.bvh", world)["8"] == tmp_path / "people_8.bvh"
    odd = World({"../up": tracks["3"], "a b": tracks["8"]}, CAMERA, "test")
    assert [p.name for p in export_paths(tmp_path / "p.bvh", odd).values()] == ["p_.._up.bvh", "p_a_b.bvh"]
    np.testing.assert_allclose(_bvh_joints(tmp_path / "people_8.bvh")[0], joints + 8, atol=1e-5)
    before = (tmp_path / "people_3.bvh").read_bytes()
    with pytest.raises(InputError, match="already exists"):
        write_world(tmp_path / "people.bvh", world)
    assert (tmp_path / "people_3.bvh").read_bytes() == before
    gappy = LiftResult(joints[:3], np.zeros((3, 17), bool), 30.0, np.array([0, 1, 5]))
    with pytest.raises(InputError, match="not consecutive"):
        write_world(tmp_path / "gappy.bvh", World({"0": gappy}, CAMERA, "test"))
    assert not (tmp_path / "gappy.bvh").exists()


def test_json_world_files_follow_the_shipped_schema(tmp_path, rng):
    import json
    from importlib import resources

    import jsonschema
    schema = json.loads(resources.files("ray3d").joinpath("assets", "world.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    world = _world(rng)
    world.tracks["7"].refinement = {"stature_m": 1.7, "body_size_m": 1.4, "median_scale": 1.0,
                                    "contact_fraction": 0.9, "position_sd_m": 0.05, "stature_sd_m": 0.03,
                                    "stature_interval_m": [1.64, 1.76], "floor_cue_fraction": 0.8,
                                    "frames": {"contact": [1, 0, 1, 1, 1], "floor_cue": [1, 1, 1, 0, 0],
                                               "floor_height_m": [0.0, 0.0, 0.0, 0.31, None]}}
    for frame in ("world", "camera"):
        document = json.loads(write_world(tmp_path / f"{frame}.json", world.in_frame(frame)).read_text())
        validator.validate(document)
    broken = dict(document, fps=0)
    assert not validator.is_valid(broken)
    del broken["fps"]
    assert not validator.is_valid(broken)
    assert not validator.is_valid(dict(document, surprise=1))  # the schema lists every field written
    document["tracks"]["7"]["joints"][0][0] = [1.0, 2.0]
    assert not validator.is_valid(document)


@pytest.mark.parametrize("path", sorted((Path(__file__).parent / "fixtures" / "old_worlds").glob("world-*")),
                         ids=lambda p: p.name)
def test_world_files_of_every_earlier_version_still_read(path):
    """Files users already have keep reading, the fields added since absent (issue 49)."""
    world = read_world(path)
    track = world.track()
    assert list(world.tracks) == ["7"] and track.joints.shape == (6, 17, 3) and np.isfinite(track.joints).all()
    np.testing.assert_allclose(world.camera.K, CAMERA.K)
    assert np.abs(track.joints[:, 0, 2] - 0.9).max() < 0.5  # a pelvis at a standing person's height
