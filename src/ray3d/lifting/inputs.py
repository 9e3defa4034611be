"""What a model reads from users' keypoints: the checks that refuse keypoints no camera could have seen (normalised
coordinates, points off the image, feet above the horizon), the shapes checked, stand-ins for joints never seen,
the one conversion to the model's input layout with its confidences (``model_inputs``) and the rays it reads
(``camera_rays``). Used by ``Lifter.lift`` and ``LiftStream`` alike; and a track made ready to lift
(``prepare_track``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ray3d import temporal
from ray3d.body import ANKLES
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.refine import joint_directions
from ray3d.skeleton import Skeleton, convert_confidences, convert_keypoints, layout_skeleton

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
    and the output flags it as filled in. The person's root must have been seen: an ``InputError`` otherwise
    (there is nothing to place them by)."""
    if never_seen[0]:
        raise InputError(f"keypoints: the root ({skeleton.joint_names[0]}, or both hips) is missing in every frame "
                         "so far (NaN or confidence 0): there is nothing to place the person by")
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


def model_inputs(keypoints: np.ndarray, skeleton: Skeleton, confidences: np.ndarray | None,
                 inputs: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Checked keypoints (..., J, 2) of ``skeleton`` and their confidences -> what a model reading ``inputs``
    takes: its (..., J_inputs, 2) pixels, which of them were found (a missing joint: NaN or confidence 0) and
    their confidences (``model_confidences``). The one conversion ``prepare_track`` and ``LiftStream`` make."""
    pixels, found = convert_keypoints(keypoints, skeleton, confidences, inputs)
    frames = keypoints.reshape(-1, *keypoints.shape[-2:])
    scores = model_confidences(frames, skeleton, None if confidences is None else
                               confidences.reshape(len(frames), -1), inputs)
    return pixels, found, scores.reshape(*keypoints.shape[:-2], -1)


def camera_rays(camera: Camera, pixels: np.ndarray, remove_roll: bool) -> np.ndarray:
    """(..., J, 2) pixels -> the (..., J, 3) rays a model reads (``Camera.pixels_to_rays``), refusing pixels the
    camera's lens model cannot invert."""
    rays = camera.pixels_to_rays(pixels, remove_roll=remove_roll)
    if not np.isfinite(rays).all():
        raise InputError(f"keypoints: some lie where camera {camera.name or ''}'s lens model cannot be inverted "
                         "(far outside the image?)")
    return rays


@dataclasses.dataclass(frozen=True)
class PreparedTrack:
    """One track made ready to lift: the model's input pixels (T, J, 2) and confidences (T, J) at the input's
    ``fps`` (gaps filled), its keypoints' ``skeleton``, the (T, 17) H36M-17 joints it did not see, and the
    (T, 17, 3) world directions of the joints' observed rays."""

    pixels: np.ndarray
    scores: np.ndarray
    fps: float
    skeleton: Skeleton
    missing: np.ndarray
    rays: np.ndarray

    @property
    def observed(self) -> np.ndarray:
        return temporal.seen_frames(self.missing)

    @property
    def feet_seen(self) -> np.ndarray:
        return ~self.missing[:, list(ANKLES)].all(axis=1)


def prepare_track(keypoints: np.ndarray, camera: Camera, confidences, fps: float | None, layout: str,
                  smooth_2d: str | None, model_skeleton: Callable[[Skeleton], Skeleton]) -> PreparedTrack:
    """One track's (T, J, 2) keypoints of ``layout`` checked and made the input of a model reading the joints
    ``model_skeleton(skeleton)`` gives (at the input's rate), and the refinement's rays."""
    if fps is not None:
        temporal.check_frame_rate(fps, "lift")
    skeleton = layout_skeleton(layout)
    keypoints, confidences = checked_keypoints(keypoints, confidences, skeleton, ("frames",))
    if len(keypoints) == 0:
        raise InputError("keypoints: no frames")
    check_in_image(keypoints, camera)
    inputs = model_skeleton(skeleton)
    pixels, found, scores = model_inputs(keypoints, skeleton, confidences, inputs)
    # The feet and the output's missing joints are read in H36M-17: the same conversion when the model reads it.
    h36m_pixels, h36m_found = (pixels, found) if inputs.name == "h36m17" else \
        convert_keypoints(keypoints, skeleton, confidences)
    check_feet_below_horizon(h36m_pixels, h36m_found, camera)
    never_seen = ~found.any(axis=0)
    input_fps = fps or MODEL_FPS
    seen_pixels = temporal.fill_missing(pixels, ~found)
    pixels = temporal.smooth(stand_in_for_unseen(seen_pixels, never_seen, inputs), smooth_2d, input_fps)
    measured = np.where(never_seen[None, :, None], np.nan, pixels)  # a stand-in is no measurement
    return PreparedTrack(pixels, scores, input_fps, skeleton, ~h36m_found, joint_directions(camera, measured, inputs))
