"""The lifted result and its world files: every format reads back what it wrote, several tracks included."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.io.world import FORMATS, LiftResult, World, read_world, write_world


def _world(rng) -> World:
    def track(frames, first):
        joints = rng.normal(0, 0.3, (frames, 17, 3)) + [2.0, 1.0, 1.0]
        interpolated = rng.random((frames, 17)) < 0.1
        return LiftResult(joints, interpolated, 30.0, np.arange(first, first + frames))

    return World({"7": track(5, 10), "person b": track(3, 0)}, cameras.h36m("S9", "54138969"), "ray3d")


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
