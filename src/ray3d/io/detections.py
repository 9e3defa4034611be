"""One person's detections over a video or a stream (``TrackDetections``): what ``Lifter.lift_tracks`` takes per
track, checked when it is laid out frame by frame."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.arrays import numeric_array

# A track is one person's stretch of one video: its frame ids span at most this many frames (28 h at 10 frames/s;
# laid out frame by frame, its arrays take about 400 MB).
LONGEST_TRACK_FRAMES = 1_000_000


class TrackDetections(NamedTuple):
    """One person's detections: frame index (N,), pixels (N, J, 2) and optional confidences (N, J)."""

    frames: np.ndarray
    pixels: np.ndarray
    confidences: np.ndarray | None = None

    def dense(self, where: str = "track") -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Every frame from the first detection to the last: (frames (T,), pixels (T, J, 2) NaN where the
        person was not detected, confidences (T, J) 0 there, or None). Refused, ``where`` named: frame ids that
        are not whole numbers, none, or spanning more than ``LONGEST_TRACK_FRAMES``; pixels not one per frame id."""
        ids = numeric_array(self.frames, f"{where}: frame ids")
        if ids.ndim != 1 or not len(ids):
            raise InputError(f"{where}: no frames" if not ids.size else f"{where}: frame ids: expected a list of "
                             f"whole numbers, got shape {ids.shape}")
        if not (np.isfinite(ids).all() and (ids == np.round(ids)).all()):
            raise InputError(f"{where}: frame ids: whole numbers expected")
        low, high = ids.min(), ids.max()
        if high - low + 1 > LONGEST_TRACK_FRAMES:
            raise InputError(f"{where}: frame ids from {low:.0f} to {high:.0f} span {high - low + 1:.0f} frames, more "
                             f"than {LONGEST_TRACK_FRAMES}: split the track (one person's stretch of one video)")
        frames = ids.astype(np.int64)
        pixels = numeric_array(self.pixels, f"{where}: pixels")
        if len(pixels) != len(frames):
            raise InputError(f"{where}: {len(frames)} frame ids for {len(pixels)} rows of pixels")
        order = np.argsort(frames)
        span = np.arange(frames[order[0]], frames[order[-1]] + 1)
        rows = frames[order] - span[0]
        dense = np.full((len(span), *pixels.shape[1:]), np.nan)
        dense[rows] = pixels[order]
        if self.confidences is None:
            return span, dense, None
        scores = numeric_array(self.confidences, f"{where}: confidences")
        if scores.shape != pixels.shape[:2]:
            raise InputError(f"{where}: confidences of shape {scores.shape} for pixels of shape {pixels.shape}")
        confidences = np.zeros(dense.shape[:2])
        confidences[rows] = scores[order]
        return span, dense, confidences
