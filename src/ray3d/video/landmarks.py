"""BlazePose's landmark network (MediaPipe Pose's ``pose_landmark_full.tflite``, bundled in the mediapipe wheel)
run through LiteRT on person crops: one person per crop, every crop of a frame in one batch.

MediaPipe's own Pose graph follows one person and its full-frame detector misses people under about 150 px;
the same landmark network given an upscaled crop around each person finds them all."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np

from ray3d.console import native_chatter_dropped
from ray3d.errors import InputError
from ray3d.skeleton import BLAZEPOSE33

INPUT_SIZE = 256
_OUTPUTS = 39  # 33 landmarks and 6 auxiliary points, each (x, y, z, visibility logit, presence logit)
_BATCHES = (8, 4, 2, 1)
HEATMAP_KERNEL = 7            # MediaPipe's pose landmark graph refines each landmark in a 7 x 7 heatmap window
HEATMAP_MIN_CONFIDENCE = 0.5
ROI_SCALE = 1.25              # MediaPipe's pose region: twice the hips-to-circle distance, times this


def mediapipe_model(relative: str, what: str) -> Path:
    """The path of a model file bundled in the mediapipe wheel (``modules/`` + ``relative``)."""
    spec = importlib.util.find_spec("mediapipe")
    if spec is None or not spec.submodule_search_locations:
        raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'")
    path = Path(next(iter(spec.submodule_search_locations))) / "modules" / relative
    if not path.is_file():
        raise InputError(f"{path}: MediaPipe's {what} is missing from the mediapipe package")
    return path


def as_regions(regions) -> np.ndarray:
    """(N, 3) or (N, 4) regions -> (N, 4): centre u, centre v, side and the crop's rotation (radians; 0 where
    not given: the image's own up)."""
    regions = np.asarray(regions, dtype=np.float64)
    regions = regions.reshape(0, 4) if regions.size == 0 else regions.reshape(len(regions), -1)
    return regions if regions.shape[1] == 4 else np.column_stack([regions, np.zeros(len(regions))])


def upright_rotation(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(N,) the crop rotation that turns the image direction ``start`` -> ``end`` (N, 2) (the mid-hips towards
    the body's circle: up the body) straight up, as MediaPipe frames a person."""
    direction = end - start
    angle = -np.pi / 2 - np.arctan2(direction[:, 1], direction[:, 0])
    return (angle + np.pi) % (2 * np.pi) - np.pi


def crop_transforms(regions) -> np.ndarray:
    """(N, 3 or 4) regions (centre u, centre v, side[, rotation]) -> (N, 2, 3) affine maps from frame pixels to
    crop pixels: ``crop = s Rot(rotation) (p - centre) + crop centre``."""
    regions = as_regions(regions)
    scale = INPUT_SIZE / regions[:, 2]
    cos, sin = np.cos(regions[:, 3]), np.sin(regions[:, 3])
    linear = scale[:, None, None] * np.stack([np.stack([cos, -sin], -1), np.stack([sin, cos], -1)], 1)
    maps = np.zeros((len(regions), 2, 3))
    maps[:, :, :2] = linear
    maps[:, :, 2] = INPUT_SIZE / 2 - np.einsum("nij,nj->ni", linear, regions[:, :2])
    return maps


def refine_from_heatmap(points: np.ndarray, heatmaps: np.ndarray, kernel: int = HEATMAP_KERNEL,
                        min_confidence: float = HEATMAP_MIN_CONFIDENCE) -> np.ndarray:
    """MediaPipe's refinement of the regressed landmarks by the network's heatmaps: (B, K, 2) crop pixels and
    (B, H, W, K) heatmap logits -> (B, K, 2), each landmark moved to the confidence-weighted mean cell of the
    ``kernel`` x ``kernel`` heatmap window around it (clipped at the heatmap's edges) where that window's peak
    confidence reaches ``min_confidence`` (as ``RefineLandmarksFromHeatmapCalculator`` does)."""
    batch, height, width, count = heatmaps.shape
    cells = np.trunc(points / INPUT_SIZE * np.array([width, height])).astype(int)  # (B, K, 2) col, row, as C++ casts
    offsets = np.arange(kernel) - (kernel - 1) // 2
    cols = cells[..., 0, None, None] + offsets[None, :]          # (B, K, 1, kernel)
    rows = cells[..., 1, None, None] + offsets[:, None]          # (B, K, kernel, 1)
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    b, k = np.arange(batch)[:, None, None, None], np.arange(count)[None, :, None, None]
    logits = heatmaps[b, np.clip(rows, 0, height - 1), np.clip(cols, 0, width - 1), k].astype(np.float64)
    confidence = np.where(inside, 1.0 / (1.0 + np.exp(-logits)), 0.0)  # (B, K, kernel, kernel)
    total = confidence.sum(axis=(-2, -1))
    mean = np.stack([(confidence * cols).sum(axis=(-2, -1)) / width, (confidence * rows).sum(axis=(-2, -1)) / height],
                    axis=-1) / np.maximum(total, 1e-12)[..., None] * INPUT_SIZE
    centre_inside = ((cells >= 0) & (cells < [width, height])).all(axis=-1)
    refine = centre_inside & (confidence.max(axis=(-2, -1)) >= min_confidence) & (total > 0)
    return np.where(refine[..., None], mean, points)


class BlazePoseLandmarks:
    """``landmarks(frame, regions)``: an (H, W, 3) uint8 RGB frame and (N, 3 or 4) regions (``crop_transforms``)
    -> pixels (N, 33, 2), per-landmark confidences (N, 33), per-crop person scores (N,) in [0, 1] and the (N, 4)
    regions to look at in the next frame."""

    layout = BLAZEPOSE33.name

    def __init__(self, threads: int = 2):
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'") from None
        self._model = str(mediapipe_model("pose_landmark/pose_landmark_full.tflite", "landmark model"))
        self._threads, self._interpreter = threads, Interpreter
        self._by_batch: dict[int, object] = {}

    def _runner(self, batch: int):
        """One interpreter per batch size: LiteRT re-plans its memory (slowly) whenever the input shape changes."""
        if batch not in self._by_batch:
            with native_chatter_dropped():  # LiteRT's "INFO: Created TensorFlow Lite XNNPACK delegate"
                runner = self._interpreter(model_path=self._model, num_threads=self._threads)
                runner.resize_tensor_input(runner.get_input_details()[0]["index"], [batch, INPUT_SIZE, INPUT_SIZE, 3])
                runner.allocate_tensors()
            outputs = {d["name"]: d["index"] for d in runner.get_output_details()}
            self._by_batch[batch] = (runner, outputs["Identity"], outputs["Identity_1"], outputs["Identity_3"])
        return self._by_batch[batch]

    def __call__(self, frame: np.ndarray, regions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        regions = as_regions(regions)
        count = len(regions)
        if count == 0:
            return np.zeros((0, 33, 2)), np.zeros((0, 33)), np.zeros(0), np.zeros((0, 4))
        maps = crop_transforms(regions)
        crops = np.stack([cv2.warpAffine(frame, m, (INPUT_SIZE, INPUT_SIZE), flags=cv2.INTER_LINEAR,
                                         borderMode=cv2.BORDER_REPLICATE) for m in maps])
        raw, scores = np.empty((count, _OUTPUTS, 5)), np.empty(count)
        start = 0
        for batch in _BATCHES:  # N crops as a sum of powers of two: few interpreters, no padding
            while count - start >= batch:
                runner, landmarks_index, score_index, heatmap_index = self._runner(batch)
                runner.set_tensor(runner.get_input_details()[0]["index"],
                                  crops[start:start + batch].astype(np.float32) / 255.0)
                runner.invoke()
                landmarks = runner.get_tensor(landmarks_index).reshape(batch, _OUTPUTS, 5)
                raw[start:start + batch] = landmarks
                raw[start:start + batch, :, :2] = refine_from_heatmap(landmarks[:, :, :2],
                                                                      runner.get_tensor(heatmap_index))
                scores[start:start + batch] = runner.get_tensor(score_index).reshape(batch)
                start += batch
        inverse = np.linalg.inv(maps[:, :, :2])
        points = np.einsum("nij,nkj->nki", inverse, raw[..., :2] - maps[:, None, :, 2])
        confidences = 1.0 / (1.0 + np.exp(-raw[:, :33, 3]))
        # The first two auxiliary points, the mid-hips and a point on the body's circle, frame the person for
        # the next frame as MediaPipe's tracking does: centred on the hips, upright.
        hips, circle = points[:, 33], points[:, 34]
        following = np.column_stack([hips, 2 * ROI_SCALE * np.linalg.norm(circle - hips, axis=-1),
                                     upright_rotation(hips, circle)])
        return points[:, :33], confidences, scores, following
