"""Where each detected person stands, for the tracker (``video.tracking.FloorTracker``): the floor point between
their ankles (x, y metres; the camera says where that pixel's ray meets the floor), how far that point may wander
(its covariance), and the colours of their clothes."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ray3d.geometry import Camera
from ray3d.skeleton import H36M17, convert_keypoints
from ray3d.video.boxes import box_overlap
from ray3d.video.clothes import clothes_boxes, clothes_colour
from ray3d.video.detectors import Detection
from ray3d.video.proposals import PersonScale

_ANKLES = [H36M17.joint_names.index("l_ankle"), H36M17.joint_names.index("r_ankle")]


class FloorPoint(NamedTuple):
    """One detection placed on the floor."""

    floor: np.ndarray  # (2,) x, y metres
    noise: np.ndarray  # (2, 2) the floor point's covariance
    colour: np.ndarray  # the clothes' colours (hue-saturation histograms of the torso and the legs)
    alone: bool  # the detection's box is clear of everybody else's: its colours are only this person's


class FloorPoints:
    """``floor_points(detections, frame)``: each detection's ``FloorPoint``, or None where the camera cannot place
    it on the floor.

    Args:
        camera: the video's camera.
        layout: the detections' joint layout.
    """

    def __init__(self, camera: Camera, layout: str):
        self.camera, self.layout = camera, layout
        self.person_height = PersonScale(camera)

    def __call__(self, detections: list[Detection], frame: np.ndarray) -> list[FloorPoint | None]:
        if not detections:
            return []
        h36m, seen = convert_keypoints(np.stack([d.pixels for d in detections]), self.layout,
                                       np.stack([d.confidences for d in detections]) >= 0.5)
        feet = np.stack([self._foot_pixel(d, p, s) for d, p, s in zip(detections, h36m, seen)])
        # The foot point wanders with the stride and the detector: a few percent of the person's height in pixels.
        sd_px = np.maximum(2.0, 0.04 * np.array([d.box[3] - d.box[1] for d in detections]))
        nudged = np.stack([feet, feet + sd_px[:, None] * [1, 0], feet + sd_px[:, None] * [0, 1]], axis=1)
        points = self.camera.pixels_to_height_plane(nudged, 0.0)  # (N, 3, 3)
        boxes = np.stack([d.box for d in detections])
        overlap = box_overlap(boxes, boxes)
        np.fill_diagonal(overlap, 0.0)
        alone = overlap.max(axis=1) < 0.05
        measured = []
        for detection, point, clear, pixels, found in zip(detections, points, alone, h36m, seen):
            if not np.isfinite(point).all():
                measured.append(None)
                continue
            spread = (point[1:, :2] - point[0, :2]).T
            noise = spread @ spread.T + np.eye(2) * 0.15 ** 2  # the stride: the ankles swing about the body
            colour = clothes_colour(frame, *clothes_boxes(detection, pixels, found))
            measured.append(FloorPoint(point[0, :2], noise, colour, clear))
        return measured

    def _foot_pixel(self, detection: Detection, pixels: np.ndarray, seen: np.ndarray) -> np.ndarray:
        """The pixel between the feet, from the detection's H36M-17 ``pixels`` (17, 2) and which are ``seen``
        (17,): the ankles where they are seen (also when the person crouches); where they are not (the legs
        hidden, or a half-body pose), no higher than the bottom of the joints seen, and as low as a person
        standing there with their head at the top."""
        ankles = pixels[_ANKLES][seen[_ANKLES]]
        if len(ankles):
            return ankles.mean(axis=0)
        x0, y0, x1, y1 = detection.box
        foot = np.array([(x0 + x1) / 2, y1])
        expected = float(self.person_height(foot))
        if np.isfinite(expected):
            foot[1] = max(y1, self.person_height.foot_below_head(foot[0], y0, expected))
        return foot
