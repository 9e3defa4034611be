"""BlazePose's landmark network (MediaPipe Pose's ``pose_landmark_full.tflite``, bundled in the mediapipe wheel)
run through LiteRT on person crops: one person per crop, every crop of a frame in one batch.

MediaPipe's own Pose graph follows one person and its full-frame detector misses people under about 150 px;
the same landmark network given an upscaled crop around each person finds them all."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np

from ray3d.errors import InputError
from ray3d.skeleton import BLAZEPOSE33

INPUT_SIZE = 256
_OUTPUTS = 39  # 33 landmarks and 6 auxiliary points, each (x, y, z, visibility logit, presence logit)
_BATCHES = (8, 4, 2, 1)


def _model_path() -> Path:
    spec = importlib.util.find_spec("mediapipe")
    if spec is None or not spec.submodule_search_locations:
        raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'")
    path = Path(next(iter(spec.submodule_search_locations))) / "modules" / "pose_landmark" / "pose_landmark_full.tflite"
    if not path.is_file():
        raise InputError(f"{path}: MediaPipe's landmark model is missing from the mediapipe package")
    return path


def crop_transforms(regions: np.ndarray) -> np.ndarray:
    """(N, 3) regions (centre u, centre v, side) -> (N, 2, 3) affine maps from frame pixels to crop pixels."""
    scale = INPUT_SIZE / regions[:, 2]
    maps = np.zeros((len(regions), 2, 3))
    maps[:, 0, 0] = maps[:, 1, 1] = scale
    maps[:, :, 2] = INPUT_SIZE / 2 - scale[:, None] * regions[:, :2]
    return maps


class BlazePoseLandmarks:
    """``landmarks(frame, regions)``: an (H, W, 3) uint8 RGB frame and (N, 3) regions -> pixels (N, 33, 2),
    per-landmark confidences (N, 33) and per-crop person scores (N,) in [0, 1]."""

    layout = BLAZEPOSE33.name

    def __init__(self, threads: int = 2):
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'") from None
        self._model, self._threads, self._interpreter = str(_model_path()), threads, Interpreter
        self._by_batch: dict[int, object] = {}

    def _runner(self, batch: int):
        """One interpreter per batch size: LiteRT re-plans its memory (slowly) whenever the input shape changes."""
        if batch not in self._by_batch:
            runner = self._interpreter(model_path=self._model, num_threads=self._threads)
            runner.resize_tensor_input(runner.get_input_details()[0]["index"], [batch, INPUT_SIZE, INPUT_SIZE, 3])
            runner.allocate_tensors()
            outputs = {d["name"]: d["index"] for d in runner.get_output_details()}
            self._by_batch[batch] = (runner, outputs["Identity"], outputs["Identity_1"])
        return self._by_batch[batch]

    def __call__(self, frame: np.ndarray, regions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        regions = np.asarray(regions, dtype=np.float64).reshape(-1, 3)
        count = len(regions)
        if count == 0:
            return np.zeros((0, 33, 2)), np.zeros((0, 33)), np.zeros(0)
        crops = np.stack([cv2.warpAffine(frame, m, (INPUT_SIZE, INPUT_SIZE), flags=cv2.INTER_LINEAR,
                                         borderMode=cv2.BORDER_REPLICATE) for m in crop_transforms(regions)])
        raw, scores = np.empty((count, _OUTPUTS, 5)), np.empty(count)
        start = 0
        for batch in _BATCHES:  # N crops as a sum of powers of two: few interpreters, no padding
            while count - start >= batch:
                runner, landmarks_index, score_index = self._runner(batch)
                runner.set_tensor(runner.get_input_details()[0]["index"],
                                  crops[start:start + batch].astype(np.float32) / 255.0)
                runner.invoke()
                raw[start:start + batch] = runner.get_tensor(landmarks_index).reshape(batch, _OUTPUTS, 5)
                scores[start:start + batch] = runner.get_tensor(score_index).reshape(batch)
                start += batch
        raw = raw[:, :33]
        scale = regions[:, 2] / INPUT_SIZE
        pixels = (raw[..., :2] - INPUT_SIZE / 2) * scale[:, None, None] + regions[:, None, :2]
        confidences = 1.0 / (1.0 + np.exp(-raw[..., 3]))
        return pixels, confidences, scores
