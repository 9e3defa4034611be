"""The time axis: which frame of a window a network predicts, the windows themselves (training samples and
whole sequences, edges replicated), resampling to the model's frame rate and back, gap filling, smoothing.

Models, lifting, streaming, evaluation and the training data all read time through this module, so a window
means the same thing everywhere. Sequences are along axis 0 unless a docstring says otherwise.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.errors import InputError

SMOOTHING_METHODS = ("savgol", "one-euro")
# How `ray3d lift`, `ray3d video`, `ray3d batch` (and lift_file / lift_video) smooth their output unless told:
# on detector-like input Savitzky-Golay cuts the joints' jitter six-fold with no lag and no loss of accuracy,
# where One-Euro at its defaults lags 0.1 s (docs/RESULTS.md, "Output smoothing"). Lifter.lift smooths only
# when asked.
OUTPUT_SMOOTHING = "savgol"


def check_frame_rate(fps, where: str) -> float:
    """``fps`` as a float, or an ``InputError`` (argument ``fps``) naming ``where`` when it is not a positive,
    finite number of frames per second."""
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.number)) or not np.isfinite(fps) or fps <= 0:
        raise InputError(f"{where}: fps must be a positive number of frames per second, got {fps!r}",
                         arguments=("fps",))
    return float(fps)


@dataclasses.dataclass(frozen=True)
class Window:
    """A network's temporal window: ``frames`` (odd) frames predicting the centre one, or, when ``causal``,
    the last one from it and the frames before (live use)."""

    frames: int
    causal: bool = False

    def __post_init__(self) -> None:
        if self.frames < 1 or self.frames % 2 == 0:
            raise InputError(f"a window's frames must be odd and positive, got {self.frames}")

    @property
    def target(self) -> int:
        """Index of the predicted frame within the window."""
        return target_frame(self.frames, self.causal)

    @property
    def delay(self) -> int:
        """How many frames after the predicted one the window still needs (0 when causal)."""
        return self.frames - 1 - self.target

    def around_target(self, frames: int) -> slice:
        """The ``frames`` (odd) frames of this window that a shorter window predicting the same frame sees."""
        if frames > self.frames or frames % 2 == 0:
            raise InputError(f"a window of {frames} frames does not fit around the target of one of {self.frames}")
        start = self.target - target_frame(frames, self.causal)
        return slice(start, start + frames)


def target_frame(frames: int, causal: bool = False) -> int:
    """Which frame of a window the network predicts: the centre (``frames // 2``), or the last for a causal
    model, which sees only the present and past frames."""
    return frames - 1 if causal else frames // 2


def window_indices(targets: np.ndarray, clip_first: np.ndarray, clip_last: np.ndarray, window: Window) -> np.ndarray:
    """(B, frames) frame indices of the windows predicting frames (B,) ``targets``, clamped into each sample's
    clip [first, last] so the edges replicate the clip's first or last frame."""
    offsets = np.arange(window.frames) - window.target
    return np.clip(targets[:, None] + offsets, clip_first[:, None], clip_last[:, None])


def sequence_window_indices(count: int, window: Window) -> np.ndarray:
    """(count, frames): every frame's window in one sequence of ``count`` frames, edges replicated."""
    targets = np.arange(count)
    return window_indices(targets, np.zeros_like(targets), np.full_like(targets, count - 1), window)


def sequence_windows(sequence: np.ndarray, window: Window) -> np.ndarray:
    """(T, frames, ...) every frame of a (T, ...) sequence with its edge-replicated window."""
    return sequence[sequence_window_indices(len(sequence), window)]


# ------------------------------------------------------------------------------------------- frame rates
def interpolate_at(sequence: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(T, ...) frames sampled at fractional frame indices (N,) ``times`` by linear interpolation, held
    constant beyond the ends."""
    last = len(sequence) - 1
    lower = np.clip(np.floor(times).astype(int), 0, last)
    upper = np.minimum(lower + 1, last)
    weight = np.clip(times - lower, 0, 1).reshape(-1, *([1] * (sequence.ndim - 1)))
    return (1 - weight) * sequence[lower] + weight * sequence[upper]


def _whole_step(native_fps: float, fps: float) -> int | None:
    """k when ``native_fps`` is (within 0.1 %) k times ``fps``: every k-th frame is taken, not interpolated."""
    ratio = native_fps / fps
    return int(round(ratio)) if abs(ratio - round(ratio)) < 1e-3 and round(ratio) >= 1 else None


def resample(sequence: np.ndarray, native_fps: float, fps: float) -> np.ndarray:
    """(F, ...) frames at ``native_fps`` -> ``fps``: every k-th frame when the ratio is a whole number k
    (no interpolation, as the shipped data), else linear interpolation in time."""
    step = _whole_step(native_fps, fps)  # BVH frame times carry few decimals
    if step is not None:
        return sequence[::step]
    times = np.arange(0.0, (len(sequence) - 1) / native_fps + 1e-9, 1.0 / fps) * native_fps
    return interpolate_at(sequence, times)


def needs_resampling(fps: float, model_fps: float) -> bool:
    return abs(fps / model_fps - 1) > 1e-3


def resample_back(sequence: np.ndarray, model_fps: float, fps: float, count: int) -> np.ndarray:
    """The inverse of ``resample(x, fps, model_fps)``: a (T', ...) sequence at ``model_fps`` read at the
    ``count`` frames of the original sequence at ``fps`` (on the same grid as ``resample`` made it: every k-th
    frame taken is frame k of the original's)."""
    step = _whole_step(fps, model_fps)
    return interpolate_at(sequence, np.arange(count) / step if step is not None else np.arange(count) / fps * model_fps)


def fill_missing(sequence: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """Linear interpolation in time of (T, J, D) values where (T, J) ``missing``; held constant at the ends. A
    joint missing in every frame is left as it is."""
    filled = sequence.copy()
    times = np.arange(len(sequence))
    for joint in range(sequence.shape[1]):
        valid = ~missing[:, joint]
        if valid.all() or not valid.any():
            continue
        for axis in range(sequence.shape[2]):
            filled[:, joint, axis] = np.interp(times, times[valid], sequence[valid, joint, axis])
    return filled


def seen_frames(missing: np.ndarray, max_missing: float = 0.5) -> np.ndarray:
    """(T,) frames in which at most ``max_missing`` of the (T, J) joints were missing (and filled in)."""
    return np.asarray(missing).mean(axis=1) <= max_missing


# --------------------------------------------------------------------------------------------- smoothing
def savgol(sequence: np.ndarray, window: int = 9, order: int = 2) -> np.ndarray:
    """Savitzky-Golay filter along time (axis 0); sequences shorter than the window are returned as they are."""
    window = min(window, len(sequence) - (1 - len(sequence) % 2))
    if window <= order:
        return sequence.copy()
    from scipy.signal import savgol_filter  # imported here: scipy.signal alone takes 0.7 s to import

    return savgol_filter(sequence, window, order, axis=0, mode="interp")


class OneEuro:
    """The One-Euro filter (Casiez et al. 2012), causal, one sample at a time, every coordinate of it at once:
    ``filter(value, dt_s)`` -> the value smoothed. Low speed -> strong smoothing (cutoff ``min_cutoff`` Hz); high
    speed -> less lag (the cutoff grows by ``beta`` per unit of speed). Samples may come at any spacing ``dt_s``
    (a live stream's dropped frames)."""

    def __init__(self, min_cutoff: float = 1.0, beta: float = 0.05, derivative_cutoff: float = 1.0):
        self.min_cutoff, self.beta, self.derivative_cutoff = min_cutoff, beta, derivative_cutoff
        self.previous: np.ndarray | None = None
        self.derivative: np.ndarray | None = None

    def __call__(self, value: np.ndarray, dt_s: float) -> np.ndarray:
        value = np.asarray(value, dtype=np.float64)
        if self.previous is None:
            self.previous, self.derivative = value.copy(), np.zeros_like(value)
            return value.copy()
        a = _smoothing_factor(self.derivative_cutoff, dt_s)
        self.derivative = a * (value - self.previous) / dt_s + (1 - a) * self.derivative
        a = _smoothing_factor(self.min_cutoff + self.beta * np.abs(self.derivative), dt_s)
        self.previous = a * value + (1 - a) * self.previous
        return self.previous.copy()


def _smoothing_factor(cutoff_hz, dt_s: float):
    return 1.0 / (1.0 + 1.0 / (2 * np.pi * cutoff_hz * dt_s))


def one_euro(sequence: np.ndarray, fps: float, min_cutoff: float = 1.0, beta: float = 0.05,
             derivative_cutoff: float = 1.0) -> np.ndarray:
    """A sequence (T, ...) through ``OneEuro`` at ``fps``."""
    smoother = OneEuro(min_cutoff, beta, derivative_cutoff)
    return np.stack([smoother(value, 1.0 / fps) for value in sequence]) if len(sequence) else \
        np.asarray(sequence, dtype=np.float64).copy()


def smooth(sequence: np.ndarray, method: str | None, fps: float) -> np.ndarray:
    """``sequence`` smoothed along time by ``method`` (None: unchanged, "savgol" or "one-euro")."""
    if method is None:
        return sequence
    if method == "savgol":
        return savgol(sequence)
    if method == "one-euro":
        return one_euro(sequence, fps)
    raise InputError(f"unknown smoothing {method!r}; one of {', '.join(SMOOTHING_METHODS)}")


def velocity(times: np.ndarray, points: np.ndarray, before_s: float, after_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(T,) seconds and (T, D) points -> (T, D) each point's velocity from the point ``before_s`` earlier to the
    one ``after_s`` later (the farthest within that span and the sequence; 0 where the span holds one point) and
    (T,) the time that spans. ``after_s = 0``: causal. One way of reading a walk's speed and heading for the site,
    the fusion's gates and the live hand-over."""
    times, points = np.asarray(times, dtype=np.float64), np.asarray(points, dtype=np.float64)
    tolerance = 1e-9  # a span of exactly so many frames includes its last
    before = np.searchsorted(times, times - before_s - tolerance, side="left")
    after = np.searchsorted(times, times + after_s + tolerance, side="right") - 1
    span = times[after] - times[before]
    moved = (points[after] - points[before]) / np.maximum(span, 1e-9)[:, None]
    moved[span <= 0] = 0.0
    return moved, span


DURATION_UNITS = {"s": 1.0, "sec": 1.0, "min": 60.0, "h": 3600.0}


def parse_duration(text) -> float:
    """A duration, ``NUMBER[UNIT]`` (s, sec, min, h; seconds without one; or a number) -> seconds (> 0);
    ``ValueError`` naming what is wrong."""
    import re

    if isinstance(text, (int, float)) and not isinstance(text, bool):
        text = str(text)
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([a-z]*)\s*", str(text).lower())
    if not match or match.group(2) not in ("", *DURATION_UNITS) or float(match.group(1)) <= 0:
        raise ValueError(f"{text!r} is not a duration: a positive number and s, min or h (15min)")
    return float(match.group(1)) * DURATION_UNITS.get(match.group(2), 1.0)

