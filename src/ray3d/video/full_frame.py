"""People in the whole frame, moving or not: MediaPipe's full-frame person detector (BlazePose's detector,
``pose_detection.tflite``, bundled in the mediapipe wheel, Apache-2.0) run through LiteRT, every person it
finds, each as the region the landmark network reads (MediaPipe's own pose region: centred on the mid-hips, 2.5
times the hips-to-body-circle distance wide).

The detector sees a 224 x 224 letterboxed copy of the frame, so it finds people from about a tenth of the
frame's long side up (the near, still and frame-filling people that motion misses); smaller, far people come
from the motion proposals (``proposals``). Its SSD head is decoded as MediaPipe's pose-detection graph does:
2254 fixed-size anchors over strides 8, 16 and 32, sigmoid scores, weighted non-maximum suppression.
"""

from __future__ import annotations

import cv2
import numpy as np

from ray3d.console import native_chatter_dropped
from ray3d.errors import InputError
from ray3d.video.boxes import box_overlap
from ray3d.video.landmarks import ROI_SCALE, mediapipe_model, upright_rotation

INPUT_SIZE = 224
STRIDES = (8, 16, 32, 32, 32)   # one entry per SSD layer; consecutive layers of one stride share a grid
ANCHORS_PER_LAYER = 2           # aspect ratio 1 and the interpolated scale
MIN_SCORE = 0.5
NMS_OVERLAP = 0.3


def ssd_anchors() -> np.ndarray:
    """(2254, 2) the anchors' centres in the 224 x 224 input, as fractions of its side."""
    centres, layer = [], 0
    while layer < len(STRIDES):
        stride, same = STRIDES[layer], 0
        while layer + same < len(STRIDES) and STRIDES[layer + same] == stride:
            same += 1
        cells = int(np.ceil(INPUT_SIZE / stride))
        y, x = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
        grid = np.stack([(x.ravel() + 0.5) / cells, (y.ravel() + 0.5) / cells], axis=-1)
        centres.append(np.repeat(grid, ANCHORS_PER_LAYER * same, axis=0))
        layer += same
    return np.concatenate(centres)


def letterbox(frame: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """An (H, W, 3) uint8 RGB frame -> (the 224 x 224 float input in [-1, 1], the scale, the (x, y) padding in
    input pixels): ``input = frame * scale + padding``."""
    height, width = frame.shape[:2]
    scale = INPUT_SIZE / max(height, width)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    resized = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
    padding = np.array([(INPUT_SIZE - size[0]) // 2, (INPUT_SIZE - size[1]) // 2])
    canvas = np.zeros((INPUT_SIZE, INPUT_SIZE, 3), dtype=np.float32)
    canvas[padding[1]:padding[1] + size[1], padding[0]:padding[0] + size[0]] = resized
    return canvas / 127.5 - 1.0, scale, padding


def decode(raw_boxes: np.ndarray, raw_scores: np.ndarray, anchors: np.ndarray,
           min_score: float = MIN_SCORE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The SSD head's (A, 12) regressions and (A,) logits -> the candidates above ``min_score``: boxes (N, 4) x0,
    y0, x1, y1, keypoints (N, 4, 2) and scores (N,), in input pixels."""
    scores = 1.0 / (1.0 + np.exp(-np.clip(raw_scores.astype(np.float64), -100.0, 100.0)))
    keep = scores >= min_score
    raw, centre = raw_boxes[keep], anchors[keep] * INPUT_SIZE
    box_centre, size = raw[:, :2] + centre, raw[:, 2:4]
    boxes = np.concatenate([box_centre - size / 2, box_centre + size / 2], axis=-1)
    keypoints = raw[:, 4:12].reshape(-1, 4, 2) + centre[:, None]
    return boxes, keypoints, scores[keep]


def weighted_suppression(boxes: np.ndarray, keypoints: np.ndarray, scores: np.ndarray,
                         overlap: float = NMS_OVERLAP) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MediaPipe's weighted non-maximum suppression: the candidates overlapping the surest one by more than
    ``overlap`` (intersection over union) are averaged into it, weighted by their scores."""
    order = np.argsort(-scores)
    kept_boxes, kept_points, kept_scores = [], [], []
    while len(order):
        ious = box_overlap(boxes[order[:1]], boxes[order])[0]
        group = order[ious > overlap]
        weights = scores[group] / scores[group].sum()
        kept_boxes.append(weights @ boxes[group])
        kept_points.append(np.einsum("n,nkd->kd", weights, keypoints[group]))
        kept_scores.append(scores[order[0]])
        order = order[ious <= overlap]
    return (np.array(kept_boxes).reshape(-1, 4), np.array(kept_points).reshape(-1, 4, 2),
            np.array(kept_scores))


class FullFramePeople:
    """``people(frame)``: an (H, W, 3) uint8 RGB frame -> (N, 4) landmark regions (centre u, centre v, side in
    frame pixels, and the rotation that stands the person upright) of every person the full-frame detector
    finds, and their (N,) scores."""

    def __init__(self, threads: int = 2, min_score: float = MIN_SCORE):
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'") from None
        with native_chatter_dropped():  # LiteRT's "INFO: Created TensorFlow Lite XNNPACK delegate"
            self._runner = Interpreter(model_path=str(mediapipe_model("pose_detection/pose_detection.tflite",
                                                                      "person detector")), num_threads=threads)
            self._runner.allocate_tensors()
        self._input = self._runner.get_input_details()[0]["index"]
        outputs = sorted(self._runner.get_output_details(), key=lambda d: d["shape"][-1])
        self._scores, self._boxes = (d["index"] for d in outputs)  # (1, A, 1) logits, (1, A, 12) regressions
        self._anchors, self.min_score = ssd_anchors(), min_score

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        image, scale, padding = letterbox(frame)
        self._runner.set_tensor(self._input, image[None])
        self._runner.invoke()
        boxes, keypoints, scores = decode(self._runner.get_tensor(self._boxes)[0],
                                          self._runner.get_tensor(self._scores)[0, :, 0], self._anchors,
                                          self.min_score)
        if not len(scores):
            return np.zeros((0, 4)), np.zeros(0)
        _, keypoints, scores = weighted_suppression(boxes, keypoints, scores)
        hips, circle = (keypoints[:, 0] - padding) / scale, (keypoints[:, 1] - padding) / scale
        side = 2 * ROI_SCALE * np.linalg.norm(circle - hips, axis=-1)
        return np.column_stack([hips, side, upright_rotation(hips, circle)]), scores
