"""Motion sets: the npz format, the performer split, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import InputError
from ray3d.data.motion import SPLITS, MotionSet, load_shipped, split_of


def test_split_is_by_performer_and_holds_both_sources(mocap_dir):
    everything = load_shipped(mocap_dir)
    performers = {split: set(load_shipped(mocap_dir, split).clips["orig_subject"])
                  for split in ("train", "validation", "test")}
    assert not performers["train"] & performers["test"] and not performers["train"] & performers["validation"]
    assert not performers["validation"] & performers["test"]
    assert set().union(*performers.values()) == set(everything.clips["orig_subject"])
    for split in ("validation", "test"):
        assert performers[split] == set(SPLITS[split])
        assert (any(p.startswith("cmu") for p in performers[split])
                and any(p.startswith("hdm05") for p in performers[split]))
    sizes = {s: load_shipped(mocap_dir, s).num_frames for s in performers}
    assert sum(sizes.values()) == everything.num_frames
    assert sizes["test"] > 10_000 and sizes["validation"] > 10_000


def test_unknown_performers_train():
    assert split_of("someone_new") == "train"


def test_save_load_round_trip_and_refusal_to_overwrite(tmp_path):
    clips = [np.random.default_rng(i).normal(size=(n, 17, 3)).astype(np.float32) for i, n in enumerate((5, 7))]
    motion = MotionSet.from_clips(clips, clip_id=["a", "b"], subject="me", fps=50.0)
    path = tmp_path / "m.npz"
    motion.save(path)
    loaded = MotionSet.load(path)
    np.testing.assert_array_equal(loaded.clip(1), clips[1])
    assert list(loaded.clips["clip_id"]) == ["a", "b"] and loaded.clips["fps"][0] == 50.0
    assert loaded.clips["native_fps"][0] == 50.0 and loaded.clips["orig_subject"][0] == "me"
    with pytest.raises(InputError, match="already exists"):
        motion.save(path)
    np.testing.assert_array_equal(MotionSet.load(path).positions, loaded.positions)  # untouched


def test_bad_npz_files(tmp_path):
    missing = tmp_path / "missing.npz"
    np.savez(missing, positions=np.zeros((4, 17, 3)))
    with pytest.raises(InputError, match=r"missing\.npz: missing key\(s\) clip_start, clip_id, fps"):
        MotionSet.load(missing)
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, positions=np.zeros((4, 16, 3)), clip_start=[0, 4], clip_id=["a"], fps=[60.0])
    with pytest.raises(InputError, match=r"positions must be \(N, 17, 3\)"):
        MotionSet.load(wrong)
    starts = tmp_path / "starts.npz"
    np.savez(starts, positions=np.zeros((4, 17, 3)), clip_start=[0, 5], clip_id=["a"], fps=[60.0])
    with pytest.raises(InputError, match="clip_start must rise from 0 to 4"):
        MotionSet.load(starts)
    not_npz = tmp_path / "text.npz"
    not_npz.write_text("hello")
    with pytest.raises(InputError, match="cannot read as a motion npz"):
        MotionSet.load(not_npz)


def test_performers_are_grounded_at_the_planted_ankle_height():
    """A performer whose planted ankle joint sits 0.16 m up (HDM05's dg) is lowered to the common height, one
    at 0.07 m is left where they are; the shift is added to the clips' floor offsets and every clip of a
    performer moves alike."""
    from ray3d.body import ANKLES, PLANTED_ANKLE_HEIGHT_M
    from ray3d.data.motion import ground_performers, planted_ankle_heights

    rng = np.random.default_rng(0)

    def standing(ankle_height: float, frames: int = 40) -> np.ndarray:
        pose = rng.normal(0, 0.2, (17, 3)) + [0.0, 0.0, 1.0]
        pose[list(ANKLES), 2] = [ankle_height, ankle_height + 0.2]
        return np.repeat(pose[None], frames, axis=0).astype(np.float32)

    motion = MotionSet.from_clips([standing(0.16), standing(0.16), standing(PLANTED_ANKLE_HEIGHT_M)],
                                  clip_id=["a", "b", "c"], subject="s", orig_subject=["dg", "dg", "cmu"])
    assert planted_ankle_heights(motion) == pytest.approx({"dg": 0.16, "cmu": PLANTED_ANKLE_HEIGHT_M}, abs=1e-6)
    grounded = ground_performers(motion)
    lowest = grounded.positions[:, list(ANKLES), 2].min(1)
    np.testing.assert_allclose(lowest, PLANTED_ANKLE_HEIGHT_M, atol=1e-6)
    np.testing.assert_allclose(grounded.positions[..., :2], motion.positions[..., :2])
    np.testing.assert_allclose(grounded.clips["floor_offset_m"], [0.09, 0.09, 0.0], atol=1e-6)
    assert planted_ankle_heights(grounded) == pytest.approx({"dg": PLANTED_ANKLE_HEIGHT_M,
                                                             "cmu": PLANTED_ANKLE_HEIGHT_M}, abs=1e-6)
