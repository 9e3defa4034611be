"""VideoPose3D-style dataset files, read from generated fixtures (never real Human3.6M data), safely."""

from __future__ import annotations

import os

import numpy as np
import pytest

from ray3d import InputError
from ray3d.data.motion import to_motion_set
from ray3d.io.dataset_files import H36M32_TO_17, load_positions_2d, load_positions_3d
from ray3d.io.safe_npz import read_npz_entries


def _fixture_3d(path, joints, subjects=("S9", "S11")):
    rng = np.random.default_rng(0)
    data = {s: {a: rng.normal(size=(n, joints, 3)).astype(np.float32) for a, n in (("Walking 1", 12), ("Sitting", 7))}
            for s in subjects}
    np.savez_compressed(path, positions_3d=data)
    return data


def test_h36m_3d_keeps_the_17_joints(tmp_path):
    data = _fixture_3d(tmp_path / "data_3d_h36m.npz", 32)
    loaded = load_positions_3d(tmp_path / "data_3d_h36m.npz")
    assert set(loaded) == {"S9", "S11"} and set(loaded["S9"]) == {"Walking 1", "Sitting"}
    np.testing.assert_allclose(loaded["S9"]["Sitting"], data["S9"]["Sitting"][:, list(H36M32_TO_17)], atol=1e-6)
    motion = to_motion_set(loaded, "h36m")
    assert motion.num_clips == 4 and motion.num_frames == 2 * (12 + 7)
    assert "S9_Walking_1" in motion.clips["clip_id"] and motion.clips["fps"][0] == 50.0


def test_h36m_2d_per_camera(tmp_path):
    rng = np.random.default_rng(1)
    per_camera = [rng.uniform(0, 1000, (9, 17, 2)).astype(np.float32) for _ in range(4)]
    metadata = {"num_joints": 17, "keypoints_symmetry": [[4, 5, 6, 11, 12, 13], [1, 2, 3, 14, 15, 16]]}
    np.savez_compressed(tmp_path / "data_2d_h36m_gt.npz", positions_2d={"S9": {"Walking": per_camera}},
                        metadata=metadata)
    loaded, meta = load_positions_2d(tmp_path / "data_2d_h36m_gt.npz")
    assert len(loaded["S9"]["Walking"]) == 4
    np.testing.assert_allclose(loaded["S9"]["Walking"][2], per_camera[2])
    assert meta["num_joints"] == 17


def test_3dhp_and_humaneva_layouts(tmp_path):
    mpi = _fixture_3d(tmp_path / "3dhp.npz", 17, ("TS1",))
    np.testing.assert_allclose(load_positions_3d(tmp_path / "3dhp.npz", "3dhp")["TS1"]["Sitting"],
                               mpi["TS1"]["Sitting"], atol=1e-6)
    humaneva = _fixture_3d(tmp_path / "humaneva.npz", 15, ("S1",))
    loaded = load_positions_3d(tmp_path / "humaneva.npz", "humaneva")
    np.testing.assert_allclose(loaded["S1"]["Sitting"],
                               humaneva["S1"]["Sitting"][:, [0, 11, 12, 13, 8, 9, 10, 14, 2, 3, 4, 5, 6, 7]], atol=1e-6)
    with pytest.raises(InputError, match="HumanEva converts to the 14-joint layout only"):
        to_motion_set(loaded, "humaneva")
    y_up = load_positions_3d(tmp_path / "3dhp.npz", "3dhp", up="y")["TS1"]["Sitting"]
    np.testing.assert_allclose(y_up[..., 2], mpi["TS1"]["Sitting"][..., 1], atol=1e-6)


def test_bad_dataset_files(tmp_path):
    _fixture_3d(tmp_path / "bad.npz", 20)
    with pytest.raises(InputError, match="20 joints is not a h36m layout"):
        load_positions_3d(tmp_path / "bad.npz")
    np.savez(tmp_path / "nokey.npz", other=np.zeros(3))
    with pytest.raises(InputError, match="missing key 'positions_3d'"):
        load_positions_3d(tmp_path / "nokey.npz")
    (tmp_path / "text.npz").write_text("no zip")
    with pytest.raises(InputError, match="not an npz file"):
        load_positions_3d(tmp_path / "text.npz")


class _Exploit:
    def __reduce__(self):
        return (os.system, ("echo pwned > /dev/null",))


def test_hostile_pickles_are_refused_not_run(tmp_path):
    path = tmp_path / "evil.npz"
    array = np.empty((), dtype=object)
    array[()] = {"S1": {"Walk": _Exploit()}}
    np.savez(path, positions_3d=array)
    with pytest.raises(InputError, match="holds objects other than arrays.*posix.system|os.system"):
        read_npz_entries(path)


def test_frames_named_by_text_say_how_they_were_ordered(tmp_path):
    """COCO-style results whose image_ids are names: by their numbers where they hold one, else in order of
    first appearance; the keypoints say which (issue 49), integer ids say nothing."""
    import json

    from ray3d.io.frame_names import FRAME_ORDERS
    from ray3d.io.keypoints import read_keypoints

    person = [float(v) for j in range(17) for v in (100 + j, 200 + 3 * j, 0.9)]

    def results(ids):
        path = tmp_path / f"r{len(list(tmp_path.iterdir()))}.json"
        path.write_text(json.dumps([{"image_id": i, "category_id": 1, "score": 1.0, "keypoints": person} for i in ids]))
        return path

    named = read_keypoints(results(["frame_0003.png", "frame_0001.png", "frame_0002.png"]))
    assert sorted(named.frames.tolist()) == [1, 2, 3]
    assert named.frame_order == FRAME_ORDERS["digits"]
    wordy = read_keypoints(results(["left.png", "right.png"]))
    assert sorted(wordy.frames.tolist()) == [0, 1] and wordy.frame_order == FRAME_ORDERS["appearance"]
    assert read_keypoints(results([4, 5])).frame_order is None
