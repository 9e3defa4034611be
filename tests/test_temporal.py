"""The time axis: window edges, target frames, resampling both ways, gap filling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from ray3d import InputError
from ray3d.temporal import (
    Window,
    fill_missing,
    interpolate_at,
    resample,
    resample_back,
    sequence_windows,
    window_indices,
)


def test_windows_replicate_the_clip_edges():
    clip = np.arange(5, dtype=float)[:, None, None] * np.ones((1, 17, 3))
    windows = sequence_windows(clip, Window(5))
    assert windows[:, :, 0, 0].tolist() == [[0, 0, 0, 1, 2], [0, 0, 1, 2, 3], [0, 1, 2, 3, 4], [1, 2, 3, 4, 4],
                                            [2, 3, 4, 4, 4]]
    idx = window_indices(np.array([10, 12]), np.array([10, 10]), np.array([12, 12]), Window(3))
    assert idx.tolist() == [[10, 10, 11], [11, 12, 12]]


def test_causal_windows_end_at_their_target():
    clip = np.arange(5, dtype=float)[:, None, None] * np.ones((1, 17, 3))
    windows = sequence_windows(clip, Window(3, causal=True))
    assert windows[:, :, 0, 0].tolist() == [[0, 0, 0], [0, 0, 1], [0, 1, 2], [1, 2, 3], [2, 3, 4]]


@pytest.mark.parametrize("frames, causal, target, delay", [(9, False, 4, 4), (9, True, 8, 0), (1, False, 0, 0),
                                                            (27, False, 13, 13)])
def test_a_window_knows_its_target_and_how_long_it_waits(frames, causal, target, delay):
    window = Window(frames, causal)
    assert (window.target, window.delay) == (target, delay)
    assert sequence_windows(np.arange(40.0), window)[20, window.target] == 20


@pytest.mark.parametrize("frames", [0, 4, -3])
def test_a_window_needs_an_odd_positive_length(frames):
    with pytest.raises(InputError, match="odd and positive"):
        Window(frames)


def test_resample_decimates_whole_ratios_and_interpolates_others():
    signal = np.arange(121, dtype=float)[:, None]
    np.testing.assert_array_equal(resample(signal, 120.0, 60.0)[:, 0], np.arange(0, 121, 2))
    out = resample(signal, 100.0, 60.0)[:, 0]
    np.testing.assert_allclose(out, np.arange(len(out)) * 100 / 60)


@settings(max_examples=60, deadline=None)
@given(st.floats(5.0, 240.0), st.integers(3, 200), st.floats(-3.0, 3.0), st.floats(-5.0, 5.0))
@example(60.03125, 3, 1.0, 0.0)  # within 0.1 % of the model's rate: taken frame by frame, and read back so
@example(120.1, 200, 1.0, 0.0)   # every second frame of a near-120 recording, read back on the same grid
def test_resampling_there_and_back_keeps_a_linear_motion(fps, count, slope, offset):
    """Linear interpolation is exact on a linear signal, so the round trip returns it wherever the model's
    frames cover the input's span (the last input frame may lie past the last model frame: held)."""
    times = np.arange(count) / fps
    signal = (offset + slope * times)[:, None]
    model = resample(signal, fps, 60.0)
    back = resample_back(model, 60.0, fps, count)
    covered = times <= (len(model) - 1) / 60.0 + 1e-12
    np.testing.assert_allclose(back[covered], signal[covered], atol=1e-9)
    assert back.shape == signal.shape


def test_interpolation_holds_the_ends():
    sequence = np.array([[0.0], [10.0], [20.0]])
    np.testing.assert_allclose(interpolate_at(sequence, np.array([-1.0, 0.5, 1.75, 5.0]))[:, 0], [0, 5, 17.5, 20])


def test_gaps_are_filled_linearly_and_held_at_the_ends():
    values = np.arange(6, dtype=float)[:, None, None] * np.ones((1, 2, 2))
    missing = np.zeros((6, 2), dtype=bool)
    missing[[0, 2, 3], 0] = True
    holed = np.where(missing[..., None], np.nan, values)
    filled = fill_missing(holed, missing)
    np.testing.assert_allclose(filled[1:, 0], values[1:, 0])
    np.testing.assert_allclose(filled[0, 0], values[1, 0])  # held before the first seen frame
    np.testing.assert_array_equal(filled[:, 1], values[:, 1])


def test_the_one_euro_filter_one_sample_at_a_time_is_the_sequence_filter_and_keeps_a_still_value():
    """``temporal.OneEuro`` (live, sample by sample, at any spacing) is the filter ``smooth(..., "one-euro")``
    runs over a sequence; a value that does not move stays put; a sample after a gap moves the output further
    towards it than one a frame later would, never past it."""
    from ray3d.temporal import OneEuro, one_euro

    walk = np.cumsum(np.random.default_rng(1).normal(0, 0.05, (50, 17, 3)), axis=0)
    smoother = OneEuro()
    np.testing.assert_allclose(np.stack([smoother(x, 0.1) for x in walk]), one_euro(walk, 10.0))
    still = OneEuro()
    assert all(np.array_equal(still(np.full(3, 2.5), 0.1), np.full(3, 2.5)) for _ in range(5))
    a, b = OneEuro(), OneEuro()
    a(np.zeros(3), 0.1), b(np.zeros(3), 0.1)
    near, far = a(np.ones(3), 0.1), b(np.ones(3), 0.5)
    assert np.all(0 < near) and np.all(near < far) and np.all(far < 1)
