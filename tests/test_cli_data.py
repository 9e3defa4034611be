"""``ray3d data``: info, importers and camera sets end to end, and their errors (exit code 2, one line)."""

from __future__ import annotations

import json

import pytest

from ray3d.cli import main
from ray3d.data.motion import MotionSet
from ray3d.io.camera_files import load_cameras


def test_data_info(mocap_dir, capsys):
    assert main(["data", "info", "--data-dir", str(mocap_dir)]) == 0
    out = capsys.readouterr().out
    assert "455 clips" in out and "test" in out and "hdm05_mm" in out and "extrinsic-test 117" in out


def test_without_data_the_error_says_what_to_do(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("RAY3D_DATA_DIR", str(tmp_path))
    assert main(["data", "info"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds none of cmu_h36m17.npz" in err


def test_import_bvh_and_amc_write_motion_npz(mocap_dir, tmp_path, capsys):
    raw = mocap_dir / "raw"
    out = tmp_path / "mine.npz"
    assert main(["data", "import-bvh", str(raw / "cgspeed_daz_bvh" / "acrnn_martial_04.bvh"), "--drop-frames", "4",
                 "--out", str(out), "--subject", "me"]) == 0
    motion = MotionSet.load(out)
    assert motion.num_frames == 657 and motion.clips["subject"][0] == "me"
    assert main(["data", "import-bvh", str(raw / "cgspeed_mb_bvh" / "02_01.bvh"), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert MotionSet.load(out).num_frames == 657  # the existing file is untouched
    amc_out = tmp_path / "amc.npz"
    assert main(["data", "import-amc", str(raw / "cmu_asfamc" / "02.asf"), str(raw / "cmu_asfamc" / "02_01.amc"),
                 "--out", str(amc_out), "--fps", "30"]) == 0
    assert MotionSet.load(amc_out).num_frames == 86


def test_cameras_json(mocap_dir, tmp_path):
    out = tmp_path / "cams.json"
    assert main(["data", "cameras", "--set", "intrinsic-test", "--out", str(out), "--data-dir", str(mocap_dir)]) == 0
    cams = load_cameras(out)
    assert len(cams) == 100 and cams[0].name.startswith("intrinsic:")
    assert json.loads(out.read_text())["set"] == "intrinsic-test"
    assert main(["data", "cameras", "--set", "train", "--out", str(tmp_path / "t.json"), "--no-filter"]) == 0
    assert len(load_cameras(tmp_path / "t.json")) == 342


@pytest.mark.parametrize("content, message", [("{", "not valid JSON"), ('{"cameras": [{"fx": 1}]}', "missing field")])
def test_bad_camera_json(tmp_path, content, message):
    from ray3d import InputError

    path = tmp_path / "c.json"
    path.write_text(content)
    with pytest.raises(InputError, match=message):
        load_cameras(path)
