"""Where people may be in a frame of a fixed camera: moving foreground (OpenCV's MOG2 background model), cut
into person-sized boxes with the camera's geometry (how tall a person standing at a floor pixel looks).

People far away are 60-130 px tall, too small for the full-frame finder at its input size but found by background
subtraction; a blob of two people walking side by side or one behind the other is split where its size says
it holds more than one person."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ray3d.body import ADULT_STATURE_M
from ray3d.geometry import Camera

ROI_MARGIN = 1.35         # a crop's side over the person's height in pixels (MediaPipe's ROI is about 1.25-1.5x)
MIN_BLOB_PX = 16          # blobs shorter than this hold nobody the landmark network could pose
MAX_REGIONS = 24          # per frame, the largest blobs first: a flickering scene cannot run away with the time


def person_height_px(camera: Camera, foot_pixels: np.ndarray, stature_m: float = ADULT_STATURE_M) -> np.ndarray:
    """(..., 2) pixels of the point between a standing person's feet -> (...,) how tall they look in pixels;
    NaN where that pixel's ray never meets the floor (above the horizon)."""
    floor = camera.pixels_to_height_plane(np.asarray(foot_pixels, dtype=np.float64), 0.0)
    reached = np.isfinite(floor).all(axis=-1)
    height = np.full(floor.shape[:-1], np.nan)
    head = camera.project(floor[reached] + np.array([0.0, 0.0, stature_m]))
    height[reached] = np.linalg.norm(head - camera.project(floor[reached]), axis=-1)
    return height


class PersonScale:
    """``person_height_px`` looked up on a grid over the image (every ``step`` pixels, interpolated): the same
    figure for many pixels without inverting the lens at each."""

    def __init__(self, camera: Camera, step: int = 8, stature_m: float = ADULT_STATURE_M):
        width, height = camera.image_size
        self._u, self._v = np.arange(0, width + step, step), np.arange(0, height + step, step)
        grid = np.stack(np.meshgrid(self._u, self._v), axis=-1).astype(np.float64)
        self._table = RegularGridInterpolator((self._v, self._u), person_height_px(camera, grid, stature_m),
                                              bounds_error=False, fill_value=None)

    def __call__(self, foot_pixels) -> np.ndarray:
        """(..., 2) foot pixels -> (...,) a person's height there in pixels (NaN above the horizon)."""
        foot = np.asarray(foot_pixels, dtype=np.float64)
        return self._table(foot[..., ::-1].reshape(-1, 2)).reshape(foot.shape[:-1])

    def foot_below_head(self, u: float, head_v: float, guess: float) -> float:
        """The foot row of a person standing in column ``u`` whose head is at row ``head_v``: v with
        v - height(v) = head_v (``guess``: a height in pixels to start from)."""
        foot = head_v + guess
        for _ in range(4):
            height = float(self([u, foot]))
            if not np.isfinite(height):
                break
            foot = head_v + height
        return foot


def median_background(frames: list[np.ndarray]) -> np.ndarray:
    """The scene without its (moving) people: the per-pixel median of frames spread over the video."""
    return np.median(np.stack(frames), axis=0).astype(np.uint8)


class ForegroundProposals:
    """``proposals(frame)`` with an (H, W, 3) uint8 frame -> (N, 3) regions of interest (centre u, centre v,
    side) in pixels, each meant to hold one person.

    Args:
        camera: the video's camera (for the size prior).
        background: an image of the empty scene (``median_background``); without one the model learns it
            from the first frames, and people in those frames leave ghosts for a while.
        history: frames the background model remembers; somebody standing still fades into it after about
            ``(1 - background_ratio) * history`` frames (30 s at 10 frames/s by default).
        min_height_fraction: the smallest blob kept, as a fraction of a person's height at its foot pixel.
    """

    def __init__(self, camera: Camera, background: np.ndarray | None = None, history: int = 1000,
                 background_ratio: float = 0.7, min_height_fraction: float = 0.35):
        self.min_height_fraction, self.person_height = min_height_fraction, PersonScale(camera)
        self._model = cv2.createBackgroundSubtractorMOG2(history=history, varThreshold=25, detectShadows=True)
        self._model.setBackgroundRatio(background_ratio)
        if background is not None:
            # Learnt as if seen for a while: a model primed with learning rate 1 calls everything new a shadow.
            for _ in range(10):
                self._model.apply(self._half(background))
        self._open = np.ones((2, 2), np.uint8)
        self._close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 9))  # joins a dark-clad person's pieces

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return self.split_blobs(self.blobs(frame))

    def blobs(self, frame: np.ndarray) -> np.ndarray:
        """(N, 4) boxes (x0, y0, x1, y1) around the moving foreground; shadows (MOG2's grey) are left out."""
        # At half resolution: a quarter of the work, and people stay tens of pixels tall.
        mask = (self._model.apply(self._half(frame)) == 255).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)
        count, _, stats, _ = cv2.connectedComponentsWithStats(mask)
        x, y, w, h, area = stats[1:].T
        keep = area >= 10
        return 2.0 * np.stack([x, y, x + w, y + h], axis=-1)[keep].astype(np.float64)

    @staticmethod
    def _half(frame: np.ndarray) -> np.ndarray:
        return cv2.resize(frame, (frame.shape[1] // 2, frame.shape[0] // 2), interpolation=cv2.INTER_AREA)

    def split_blobs(self, boxes: np.ndarray) -> np.ndarray:
        """Boxes (N, 4) -> person regions (M, 3), largest blobs first and at most ``MAX_REGIONS``: a blob wider
        or taller than one person at its foot pixel is cut into several; blobs much smaller than a person there
        (or than ``MIN_BLOB_PX``) are dropped."""
        regions = []
        for x0, y0, x1, y1 in sorted(boxes, key=lambda b: -(b[2] - b[0]) * (b[3] - b[1])):
            width, height = x1 - x0, y1 - y0
            person = float(self.person_height([(x0 + x1) / 2, y1]))
            if not np.isfinite(person) or height < max(MIN_BLOB_PX, self.min_height_fraction * person):
                continue
            columns = max(1, int(round(width / (0.35 * person)))) if width > 0.55 * person else 1
            centres_u = x0 + (np.arange(columns) + 0.5) * width / columns
            rows = [(y0 + y1) / 2, max(height, 0.7 * person)] if height <= 1.4 * person else None
            for u in centres_u:
                if rows is not None and columns == 1:
                    regions.append((u, rows[0], ROI_MARGIN * rows[1]))
                    continue
                # Side by side or one behind the other: a person standing at the blob's bottom, and, when the blob
                # is taller than that person, one whose head is at its top.
                regions.append((u, y1 - person / 2, ROI_MARGIN * person))
                if height > 1.4 * person:
                    foot = self.person_height.foot_below_head(u, y0, person)
                    regions.append((u, (y0 + foot) / 2, ROI_MARGIN * (foot - y0)))
        return np.array(regions[:MAX_REGIONS], dtype=np.float64).reshape(-1, 3)

    def unexplained(self, blobs: np.ndarray, people: np.ndarray) -> np.ndarray:
        """Regions (M, 3) for the parts of blobs (N, 4) that none of the people found (boxes (K, 4)) covers: the
        second of two people walking close together, whom a crop holding both showed only one of."""
        regions = []
        for x0, y0, x1, y1 in blobs:
            person = float(self.person_height([(x0 + x1) / 2, y1]))
            if not np.isfinite(person) or y1 - y0 < 0.5 * person:
                continue
            columns = np.arange(int(x0), int(np.ceil(x1)))
            covered = np.zeros(len(columns), dtype=bool)
            for a0, b0, a1, b1 in people:
                if b1 > y0 and b0 < y1:  # beside each other in the blob's rows
                    margin = 0.15 * (b1 - b0)  # arms, legs and shadow beyond the joints
                    covered |= (columns >= a0 - margin) & (columns <= a1 + margin)
            if covered.all() or not covered.any():
                continue  # wholly explained, or nobody found in it at all (it had its own crop already)
            runs = np.split(columns[~covered], np.flatnonzero(np.diff(columns[~covered]) > 1) + 1)
            widest = max(runs, key=len)
            if len(widest) >= 0.3 * person:
                regions.append((widest.mean(), y1 - person / 2, ROI_MARGIN * person))
        return np.array(regions, dtype=np.float64).reshape(-1, 3)
