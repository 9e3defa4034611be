"""What a model reads from users' keypoints: the checks that refuse keypoints no camera could have seen (normalised
coordinates, points off the image, feet above the horizon), the shapes checked, stand-ins for joints never seen,
and the confidences in the model's input layout. Used by ``Lifter.lift`` and ``LiftStream`` alike."""

from __future__ import annotations

import numpy as np

from ray3d.body import ANKLES
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.skeleton import Skeleton, convert_confidences

MODEL_FPS = 60.0  # the frame rate of the motion the shipped models were trained on


def check_in_image(keypoints: np.ndarray, camera: Camera) -> None:
    """Refuse keypoints normalised to 0-1 and keypoints that do not fit the camera's image."""
    seen = keypoints[np.isfinite(keypoints).all(-1)]
    width, height = camera.image_size
    if not len(seen):
        return
    if np.abs(seen).max() <= 1.5 and max(width, height) > 16:
        raise InputError("keypoints: every coordinate lies within 0-1.5: they look normalised to the image size; "
                         "give them in pixels")
    margin = 0.25 * np.array([width, height])
    inside = np.mean(((seen >= -margin) & (seen <= [width, height] + margin)).all(-1))
    if inside < 0.5:
        raise InputError(f"keypoints: {100 * (1 - inside):.0f}% lie outside camera {camera.name or ''}'s "
                         f"{width}x{height} image (by more than a quarter of it): the wrong camera or image size?")


# Feet seen above the horizon (rays rising by more than ~2 degrees) from a camera higher than this cannot be
# feet on the floor: the camera's pitch or orientation is wrong (e.g. a sign error: up instead of down).
_HIGHEST_FEET_CAMERA_M = 0.3
_FEET_RISE = 0.035


def check_feet_below_horizon(pixels: np.ndarray, found: np.ndarray, camera: Camera) -> None:
    """Refuse a camera that would see the person's feet, most of the time, on rays rising above the horizon:
    (T, 17, 2) H36M-17 pixels, (T, 17) which were detected (the ankles are the detector's own)."""
    if camera.center[2] <= _HIGHEST_FEET_CAMERA_M:
        return
    seen = pixels[:, ANKLES][found[:, ANKLES]]
    if not len(seen):
        return
    directions = camera.pixels_to_world_directions(seen)
    rising = np.mean(directions[:, 2] / np.linalg.norm(directions, axis=-1) > _FEET_RISE)
    if rising > 0.5:
        raise InputError(f"keypoints: through camera {camera.name or ''} ({camera.center[2]:.1f} m above the floor) "
                         f"the feet lie above the horizon in {100 * rising:.0f}% of "
                         "detections, where no one standing on the floor can be: check the camera's pitch "
                         "(positive looks down) or its rotation", arguments=("camera",))


def checked_keypoints(keypoints, confidences, skeleton: Skeleton,
                      leading: tuple[str, ...] = ()) -> tuple[np.ndarray, np.ndarray | None]:
    """``keypoints`` (*leading, J, 2) pixels of ``skeleton``'s layout and optional ``confidences`` (*leading, J)
    as float arrays, their shapes checked."""
    keypoints = np.asarray(keypoints, dtype=np.float64)
    if keypoints.ndim != len(leading) + 2 or keypoints.shape[len(leading):] != (skeleton.num_joints, 2):
        expected = ", ".join([*leading, str(skeleton.num_joints), "2"])
        raise InputError(f"keypoints: expected ({expected}) for layout {skeleton.name}, got {keypoints.shape}")
    if confidences is not None:
        confidences = np.asarray(confidences, dtype=np.float64)
        if confidences.shape != keypoints.shape[:-1]:
            raise InputError(f"confidences: expected shape {keypoints.shape[:-1]}, got {confidences.shape}")
    return keypoints, confidences


def stand_in_for_unseen(pixels: np.ndarray, never_seen: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, J, 2) pixels of ``skeleton`` with each joint ``never_seen`` (J,) placed on its parent (parents come
    first), as training simulates a detector's miss: the network then predicts it from the rest of the body,
    and the output flags it as filled in."""
    pixels = pixels.copy()
    for joint, parent in enumerate(skeleton.parents):
        if never_seen[joint] and parent >= 0:
            pixels[:, joint] = pixels[:, parent]
    return pixels


def model_confidences(keypoints: np.ndarray, skeleton: Skeleton, confidences: np.ndarray | None,
                      inputs: Skeleton) -> np.ndarray:
    """The (T, J_inputs) confidences a model reads: the detector's (clipped to [0, 1]; 1 where it gave none),
    0 where a joint is missing, converted to the model's input layout (a derived joint as sure as its least
    sure source)."""
    seen = np.isfinite(keypoints).all(-1)
    scores = np.ones(seen.shape) if confidences is None else np.clip(np.nan_to_num(confidences), 0.0, 1.0)
    return convert_confidences(np.where(seen, scores, 0.0), skeleton, inputs)
