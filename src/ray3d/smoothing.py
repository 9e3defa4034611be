"""Temporal smoothing of keypoint or joint sequences along axis 0: Savitzky-Golay and the One-Euro filter."""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from ray3d.errors import InputError

METHODS = ("savgol", "one-euro")


def savgol(sequence: np.ndarray, window: int = 9, order: int = 2) -> np.ndarray:
    """Savitzky-Golay filter along time (axis 0); sequences shorter than the window are returned as they are."""
    window = min(window, len(sequence) - (1 - len(sequence) % 2))
    if window <= order:
        return sequence.copy()
    return savgol_filter(sequence, window, order, axis=0, mode="interp")


def one_euro(sequence: np.ndarray, fps: float, min_cutoff: float = 1.0, beta: float = 0.05,
             derivative_cutoff: float = 1.0) -> np.ndarray:
    """The One-Euro filter (Casiez et al. 2012), causal, vectorised over all coordinates of each frame.

    Low speed -> strong smoothing (cutoff ``min_cutoff`` Hz); high speed -> less lag (cutoff grows by ``beta``
    per unit of speed).
    """
    def alpha(cutoff):
        tau = 1.0 / (2 * np.pi * cutoff)
        return 1.0 / (1.0 + tau * fps)

    out = np.empty_like(sequence, dtype=np.float64)
    out[0] = sequence[0]
    derivative = np.zeros_like(out[0])
    for i in range(1, len(sequence)):
        raw_derivative = (sequence[i] - out[i - 1]) * fps
        a = alpha(derivative_cutoff)
        derivative = a * raw_derivative + (1 - a) * derivative
        a = alpha(min_cutoff + beta * np.abs(derivative))
        out[i] = a * sequence[i] + (1 - a) * out[i - 1]
    return out


def smooth(sequence: np.ndarray, method: str | None, fps: float) -> np.ndarray:
    if method is None:
        return sequence
    if method == "savgol":
        return savgol(sequence)
    if method == "one-euro":
        return one_euro(sequence, fps)
    raise InputError(f"unknown smoothing {method!r}; one of {', '.join(METHODS)}")
