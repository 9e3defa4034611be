"""Metrics against hand-computed values, invariances, numpy/torch parity."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ray3d import InputError, metrics


def test_hand_computed_values():
    target = np.zeros((1, 3, 3))
    target[0, 1] = [1.0, 0.0, 0.0]
    target[0, 2] = [0.0, 1.0, 0.0]
    predicted = target.copy()
    predicted[0, 0] += [0.0, 0.0, 3.0]  # root moved 3 along z
    predicted[0, 2] += [0.0, 0.0, 4.0]  # one joint moved 4 along z
    assert metrics.abs_mpjpe(predicted, target) == pytest.approx((3 + 0 + 4) / 3)
    assert metrics.mrpe(predicted, target) == pytest.approx(3.0)
    # Root-relative: the root error is removed, the other joints are off by (0,0,-3) and (0,0,1).
    assert metrics.mpjpe(predicted, target) == pytest.approx((0 + 3 + 1) / 3)


def test_mrpe_uses_the_root_joint_only():
    rng = np.random.default_rng(0)
    target = rng.normal(size=(10, 17, 3))
    predicted = target + np.concatenate([np.zeros((10, 1, 3)), rng.normal(size=(10, 16, 3))], axis=1)
    assert metrics.mrpe(predicted, target) == 0.0
    shifted = target + np.array([0.0, 0.5, 0.0])
    assert metrics.mrpe(shifted, target) == pytest.approx(0.5)
    assert metrics.mpjpe(shifted, target) == pytest.approx(0.0)


def test_reduction_none_gives_per_frame_values():
    rng = np.random.default_rng(1)
    target, predicted = rng.normal(size=(2, 4, 5, 17, 3))
    for metric in (metrics.mpjpe, metrics.p_mpjpe, metrics.abs_mpjpe, metrics.mrpe):
        per_frame = metric(predicted, target, reduction="none")
        assert per_frame.shape == (4, 5)
        assert per_frame.mean() == pytest.approx(metric(predicted, target))
    assert metrics.mpjve(predicted, target, reduction="none").shape == (4, 4)


@given(seed=st.integers(0, 10_000), scale=st.floats(0.2, 5.0))
@settings(max_examples=60, deadline=None)
def test_p_mpjpe_is_invariant_to_similarity_transforms(seed, scale):
    rng = np.random.default_rng(seed)
    target = rng.normal(size=(3, 17, 3))
    predicted = target + rng.normal(scale=0.05, size=target.shape)
    rotation = Rotation.random(random_state=seed).as_matrix()
    moved = scale * predicted @ rotation.T + rng.normal(size=3)
    assert metrics.p_mpjpe(moved, target) == pytest.approx(metrics.p_mpjpe(predicted, target), rel=1e-7, abs=1e-10)
    assert metrics.p_mpjpe(scale * target @ rotation.T + 1.0, target) == pytest.approx(0.0, abs=1e-9)


def test_p_mpjpe_does_not_allow_reflections():
    target = np.random.default_rng(3).normal(size=(1, 17, 3))
    mirrored = target * np.array([-1.0, 1.0, 1.0])
    assert metrics.p_mpjpe(mirrored, target) > 0.1


def test_mpjve_hand_computed():
    target = np.zeros((3, 2, 3))
    predicted = target.copy()
    predicted[2, :, 0] = 1.0  # last frame jumps by 1 in x
    assert metrics.mpjve(predicted, target, reduction="none").tolist() == [0.0, 1.0]
    with pytest.raises(InputError, match="T >= 2"):
        metrics.mpjve(predicted[:1], target[:1])


def test_torch_matches_numpy_and_has_gradients():
    rng = np.random.default_rng(4)
    target, predicted = rng.normal(size=(2, 8, 17, 3))
    tensor = torch.tensor(predicted, requires_grad=True)
    for metric in (metrics.mpjpe, metrics.p_mpjpe, metrics.abs_mpjpe, metrics.mrpe, metrics.mpjve):
        value = metric(tensor, torch.tensor(target))
        assert value.item() == pytest.approx(metric(predicted, target), rel=1e-9)
    metrics.mpjpe(tensor, torch.tensor(target)).backward()
    assert torch.isfinite(tensor.grad).all()


def test_grouped_mean_weights_frames_within_and_groups_equally():
    values = np.array([1.0, 1.0, 1.0, 4.0])
    overall, per_group = metrics.grouped_mean(values, ["walk", "walk", "walk", "sit"])
    assert per_group == {"walk": 1.0, "sit": 4.0}
    assert overall == pytest.approx(2.5)
    assert metrics.grouped_mean(torch.tensor(values), ["a", "b", "a", "b"])[1] == {"a": 1.0, "b": 2.5}
    with pytest.raises(InputError, match="4 values but 3 group labels"):
        metrics.grouped_mean(values, ["a", "b", "c"])


def test_mismatched_shapes_raise():
    with pytest.raises(InputError, match="same shape"):
        metrics.mpjpe(np.zeros((2, 17, 3)), np.zeros((2, 16, 3)))
    with pytest.raises(InputError, match="reduction"):
        metrics.mpjpe(np.zeros((2, 17, 3)), np.zeros((2, 17, 3)), reduction="sum")


def _track(frames, xs, y=0.0):
    """A track standing at (x, y) on the floor in each of ``frames``."""
    frames = np.asarray(frames)
    root = np.zeros((len(frames), 3))
    root[:, 0], root[:, 1], root[:, 2] = xs, y, 0.9  # the pelvis's height does not count
    return SimpleNamespace(frames=frames, root=root)


def test_match_tracks_pairs_each_track_with_the_nearest_that_shares_its_frames():
    first = {"a": _track(range(10), np.arange(10.0)), "b": _track(range(5, 15), 3.0, y=5.0),
             "lonely": _track(range(100, 110), 0.0)}
    second = {"x": _track(range(0, 8), np.arange(8.0) + 0.1, y=0.2),  # a's walk, 0.1 m along and 0.2 m across
              "y": _track(range(0, 10), np.arange(10.0), y=3.0),  # a's frames, 3 m off
              "z": _track(range(10, 20), 3.0, y=5.5)}  # b's second half only
    matches = {m.first: m for m in metrics.match_tracks(first, second)}
    assert set(matches) == {"a", "b"}  # "lonely" shares no frame with any
    assert matches["a"].second == "x" and matches["a"].frames.tolist() == list(range(8))
    assert matches["a"].median_m == pytest.approx(np.hypot(0.1, 0.2))
    assert matches["b"].second == "z" and len(matches["b"].frames) == 5 and matches["b"].median_m == pytest.approx(0.5)
    # b shares only half its frames with z; asking for more leaves it unmatched; a within 0.1 m: none near enough
    assert [m.first for m in metrics.match_tracks(first, second, min_share=0.6)] == ["a"]
    assert [m.first for m in metrics.match_tracks(first, second, within_m=0.3)] == ["a"]
    assert metrics.match_tracks(first, second, within_m=0.1) == []
