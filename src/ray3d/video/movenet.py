"""People in the whole frame from any side, no face needed: MoveNet MultiPose Lightning (Google, Apache-2.0;
``assets/models/movenet_multipose_lightning.tflite``, the float16 file as its authors published it, shipped in
ray3d's wheel with its licence) run through LiteRT. It finds up to six people a pass by their whole body (a person
walking away, in profile, or with the head hidden by somebody else's), each with a box and 17 COCO keypoints; each
becomes the region BlazePose's landmark network reads (``landmarks``), as the motion proposals' do.

The model sees the frame resized with its aspect kept, the long side ``input_size`` pixels (a multiple of 32).
People under about a tenth of that are lost, and it finds six at most: where people are small or many, the frame is
cut into ``tiles`` (columns, rows) overlapping by a quarter, each seen at ``input_size``, and the people found twice
where tiles overlap kept once.
"""

from __future__ import annotations

from importlib import resources

import cv2
import numpy as np

from ray3d.console import native_chatter_dropped
from ray3d.errors import InputError
from ray3d.skeleton import BLAZEPOSE33, COCO17
from ray3d.video.boxes import box_inside, box_overlap
from ray3d.video.landmarks import as_regions, upright_rotation
from ray3d.video.proposals import ROI_MARGIN

MODEL_FILE = "movenet_multipose_lightning.tflite"
PEOPLE_PER_PASS = 6
KEYPOINTS = 17
MIN_SCORE = 0.15            # the person score (MoveNet's box score) below which a box holds nobody
MIN_KEYPOINT_SCORE = 0.3    # a keypoint this sure orients the crop
# MoveNet's keypoint scores are not BlazePose's visibilities: one of SEEN_SCORE or more is a keypoint seen (MoveNet's
# own demos draw from 0.1-0.3), which the video pipeline's confidences put at 0.5.
SEEN_SCORE = 0.25
SAME_PERSON_OVERLAP = 0.5   # two tiles' boxes overlapping this much (IoU), or one mostly inside the other: one person
TILE_OVERLAP = 0.25
# COCO-17 indices: the shoulders and hips, whose midpoints stand the crop upright as MediaPipe frames a person.
SHOULDERS, HIPS = (5, 6), (11, 12)


def model_path() -> str:
    """The shipped MoveNet file's path."""
    path = resources.files("ray3d").joinpath("assets", "models", MODEL_FILE)
    if not path.is_file():
        raise InputError(f"{path}: MoveNet's model file is missing from the ray3d package (reinstall ray3d)")
    return str(path)


def tile_boxes(width: int, height: int, tiles: tuple[int, int]) -> np.ndarray:
    """(columns x rows, 4) x0, y0, x1, y1 in frame pixels: a (width, height) frame cut into ``tiles`` (columns,
    rows) of equal size that overlap their neighbours by ``TILE_OVERLAP`` of a tile and together cover it."""
    columns, rows = (max(1, int(n)) for n in tiles)
    boxes = []
    for count, side in ((columns, width), (rows, height)):
        size = side / (count - (count - 1) * TILE_OVERLAP)
        starts = np.arange(count) * size * (1 - TILE_OVERLAP)
        boxes.append(np.stack([starts, np.minimum(starts + size, side)], axis=-1))
    return np.array([[x0, y0, x1, y1] for y0, y1 in boxes[1] for x0, x1 in boxes[0]])


def input_shape(width: float, height: float, input_size: int) -> tuple[int, int]:
    """(width, height) of the model input for an image of (width, height): the long side ``input_size``, the
    aspect kept, each a multiple of 32 (the model's strides)."""
    scale = input_size / max(width, height)
    return tuple(max(32, int(np.floor(side * scale / 32 + 0.5)) * 32) for side in (width, height))


def decode(output: np.ndarray, origin: np.ndarray, size: np.ndarray, min_score: float = MIN_SCORE
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MoveNet's (6, 56) output for an image whose top-left corner is ``origin`` (2,) and size ``size`` (2,) in
    frame pixels -> the people above ``min_score``: boxes (N, 4) x0, y0, x1, y1 and keypoints (N, 17, 3) (u, v,
    score) in frame pixels, and scores (N,). The output's rows: 17 keypoints (y, x, score), then the box (y0, x0,
    y1, x1) and its score, all coordinates as fractions of the image."""
    output = np.asarray(output, dtype=np.float64).reshape(PEOPLE_PER_PASS, -1)
    people = output[output[:, 55] >= min_score]
    points = people[:, :3 * KEYPOINTS].reshape(-1, KEYPOINTS, 3)
    keypoints = np.concatenate([origin + points[..., 1::-1] * size, points[..., 2:]], axis=-1)
    y0, x0, y1, x1 = people[:, 51:55].T
    boxes = np.stack([x0, y0, x1, y1], axis=-1) * np.tile(size, 2) + np.tile(origin, 2)
    return boxes, keypoints, people[:, 55]


def once_each(boxes: np.ndarray, keypoints: np.ndarray, scores: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of the people found more than once (in two overlapping tiles: boxes overlapping by ``SAME_PERSON_OVERLAP``,
    or one's box mostly inside the other's, a person cut by a tile's edge), the surest."""
    kept: list[int] = []
    for index in np.argsort(-scores, kind="stable"):
        if all(box_overlap(boxes[index][None], boxes[other][None])[0, 0] < SAME_PERSON_OVERLAP
               and box_inside(boxes[index], boxes[other]) < 0.8 and box_inside(boxes[other], boxes[index]) < 0.8
               for other in kept):
            kept.append(int(index))
    return boxes[kept], keypoints[kept], scores[kept]


def person_regions(boxes: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """(N, 4) boxes and (N, 17, 3) keypoints -> (N, 4) landmark regions (centre u, centre v, side, rotation): the
    box's centre, ``ROI_MARGIN`` times its longer side, turned so that the mid-hips -> mid-shoulders direction points
    up where those four keypoints are sure (a person lying, bending), upright otherwise (a fixed camera's people)."""
    centre = (boxes[:, :2] + boxes[:, 2:]) / 2
    side = ROI_MARGIN * np.max(boxes[:, 2:] - boxes[:, :2], axis=-1)
    hips, shoulders = keypoints[:, HIPS, :2].mean(axis=1), keypoints[:, SHOULDERS, :2].mean(axis=1)
    sure = (keypoints[:, HIPS + SHOULDERS, 2] >= MIN_KEYPOINT_SCORE).all(axis=1)
    rotation = np.where(sure, upright_rotation(hips, shoulders), 0.0) if len(boxes) else np.zeros(0)
    return as_regions(np.column_stack([centre, side, rotation]))


def as_blazepose(keypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 17, 3) COCO-17 keypoints (u, v, MoveNet's score) -> (N, 33, 2) pixels and (N, 33) confidences in
    BlazePose-33's layout (the video pipeline's): the 17 where BlazePose has them, their scores mapped so that
    ``SEEN_SCORE`` is 0.5; BlazePose's other points (hands, feet, eyes' corners, mouth) at their parent's pixel,
    unseen (confidence 0)."""
    keypoints = np.asarray(keypoints, dtype=np.float64).reshape(-1, len(COCO17.joint_names), 3)
    pixels = np.zeros((len(keypoints), BLAZEPOSE33.num_joints, 2))
    confidences = np.zeros((len(keypoints), BLAZEPOSE33.num_joints))
    score = keypoints[..., 2]
    mapped = np.where(score >= SEEN_SCORE, 0.5 + 0.5 * (score - SEEN_SCORE) / (1 - SEEN_SCORE),
                      0.5 * score / SEEN_SCORE)
    for coco, name in enumerate(COCO17.joint_names):
        pixels[:, BLAZEPOSE33.index(name)] = keypoints[:, coco, :2]
        confidences[:, BLAZEPOSE33.index(name)] = mapped[:, coco]
    for joint, parent in enumerate(BLAZEPOSE33.parents):  # parents come before their children
        if BLAZEPOSE33.joint_names[joint] not in COCO17.joint_names:
            pixels[:, joint] = pixels[:, parent]
    return pixels, confidences


class MoveNetPeople:
    """``people(frame)``: an (H, W, 3) uint8 RGB frame -> (N, 4) landmark regions (centre u, centre v, side,
    rotation) of everybody MoveNet finds and their (N,) scores; ``people.found(frame)`` the boxes, keypoints and
    scores themselves (frame pixels).

    Args:
        threads: CPU threads for the model.
        input_size: the long side of the image the model sees (a multiple of 32): larger finds smaller people,
            at about the square's cost.
        tiles: (columns, rows) the frame is cut into, each seen at ``input_size``.
        min_score: MoveNet's person score below which a box holds nobody.
    """

    def __init__(self, threads: int = 2, input_size: int = 384, tiles: tuple[int, int] = (1, 1),
                 min_score: float = MIN_SCORE):
        if input_size < 32 or input_size % 32:
            raise InputError(f"input_size: a positive multiple of 32 pixels, got {input_size}", ("input_size",))
        if len(tiles) != 2 or min(tiles) < 1:
            raise InputError(f"tiles: (columns, rows), each at least 1, got {tiles}", ("tiles",))
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError:
            raise InputError("the video detectors need the video extra: pip install 'ray3d[video]'") from None
        with native_chatter_dropped():  # LiteRT's "INFO: Created TensorFlow Lite XNNPACK delegate"
            self._runner = Interpreter(model_path=model_path(), num_threads=threads)
        self._input = self._runner.get_input_details()[0]["index"]
        self._output = self._runner.get_output_details()[0]["index"]
        self.input_size, self.tiles, self.min_score = int(input_size), tuple(int(n) for n in tiles), min_score
        self._shape: tuple[int, int] | None = None

    def _run(self, image: np.ndarray) -> np.ndarray:
        """One pass on an (h, w, 3) uint8 image already at the model's input shape -> its (6, 56) output."""
        shape = image.shape[:2]
        if shape != self._shape:  # the input's size is the model's to choose per call; resized only when it changes
            self._runner.resize_tensor_input(self._input, [1, *shape, 3])
            with native_chatter_dropped():  # where LiteRT makes its delegate and says so
                self._runner.allocate_tensors()
            self._shape = shape
        self._runner.set_tensor(self._input, np.ascontiguousarray(image[None]))
        self._runner.invoke()
        return self._runner.get_tensor(self._output)[0]

    def found(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 4) boxes, (N, 17, 3) keypoints (u, v, score) and (N,) scores of the people in the frame."""
        height, width = frame.shape[:2]
        everyone = []
        for x0, y0, x1, y1 in tile_boxes(width, height, self.tiles):
            a0, b0, a1, b1 = int(round(x0)), int(round(y0)), int(round(x1)), int(round(y1))
            shape = input_shape(a1 - a0, b1 - b0, self.input_size)
            image = cv2.resize(frame[b0:b1, a0:a1], shape, interpolation=cv2.INTER_AREA)
            everyone.append(decode(self._run(image), np.array([a0, b0], float), np.array([a1 - a0, b1 - b0], float),
                                   self.min_score))
        boxes, keypoints, scores = (np.concatenate(parts) for parts in zip(*everyone))
        return once_each(boxes, keypoints, scores) if len(everyone) > 1 else (boxes, keypoints, scores)

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes, keypoints, scores = self.found(frame)
        return person_regions(boxes, keypoints), scores
