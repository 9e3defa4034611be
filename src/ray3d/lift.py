"""``Lifter``: users' 2D keypoints and calibrated camera -> 3D joints in metres in the world frame.

Handles what real keypoints bring: other joint layouts (COCO-17, BlazePose-33, OpenPose BODY-25), missing joints
(NaN or confidence 0: interpolated in time and reported), other frame rates (resampled to the model's and back),
sequences shorter than the receptive field (edge-replicated), several people (each track lifted on its own into
one world frame), long sequences (in chunks), smoothing of the 2D input and 3D output, and a GPU when there is one.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ray3d import temporal
from ray3d.body import ANKLES
from ray3d.checkpoints import default_model, load_model
from ray3d.errors import InputError
from ray3d.geometry import Camera, CameraBatch
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.io.keypoints import Keypoints, TrackDetections
from ray3d.io.world import LiftResult, World
from ray3d.models.inference import inference_network
from ray3d.models.network import LiftingNetwork, predict_world
from ray3d.models.tensor_batch import TensorBatch
from ray3d.options import LiftOptions
from ray3d.refine import RefineConfig, joint_directions, network_position_sd, refine_track
from ray3d.skeleton import (Skeleton, conversion_matrix, convert_confidences, convert_keypoints,
                            layout_skeleton)

MODEL_FPS = 60.0  # the frame rate of the motion the shipped models were trained on


def _check_in_image(keypoints: np.ndarray, camera: Camera) -> None:
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


def _check_feet_below_horizon(pixels: np.ndarray, found: np.ndarray, camera: Camera) -> None:
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


class LiftedTracks(dict):
    """{track id: LiftResult} of the tracks lifted, and ``unliftable``: {track id: why} of those that could not
    be."""

    def __init__(self) -> None:
        super().__init__()
        self.unliftable: dict = {}


class Lifter:
    """A trained network ready to lift. ``Lifter.load()`` gives the shipped Ray3D weights."""

    def __init__(self, model, document: dict, device: str | torch.device | None = None, name: str | None = None):
        self.document = document
        self.name = name or model.config.name  # how world files name the model that lifted them
        if isinstance(model, LiftingNetwork):
            self.device = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
            self.model = inference_network(model).to(self.device)
        else:  # the TorchScript and ONNX Runtime backends run on the CPU
            self.device, self.model = torch.device("cpu"), model

    @classmethod
    def load(cls, name_or_path: str | None = None, device: str | None = None, backend: str = "torch",
             image_width: float = 1000.0, layout: str = "h36m17") -> Lifter:
        """A shipped model by name (``ray3d``, ``ray3d-real``, ``videopose3d``, ...) or a checkpoint path; without
        one, the shipped model for keypoints of ``layout`` (``checkpoints.default_model``: ``ray3d`` for H36M-17,
        ``ray3d-real`` for a detector's layout).

        ``backend="torchscript"`` runs a frozen TorchScript trace on the CPU (lowest latency with torch alone:
        live use); ``backend="onnx"`` runs it with ONNX Runtime (``pip install 'ray3d[onnx]'``). Pixel-input
        models are then built for images ``image_width`` pixels wide.
        """
        name_or_path = name_or_path or default_model(layout)
        model, document = load_model(name_or_path)
        if backend in ("torchscript", "onnx"):
            from ray3d.models import backends

            runner = (backends.TorchScriptLiftingModel(model, image_width) if backend == "torchscript"
                      else backends.OnnxLiftingModel(model, image_width))
            return cls(runner, document, name=str(name_or_path))
        if backend != "torch":
            raise InputError(f"unknown backend {backend!r}; 'torch', 'torchscript' or 'onnx'")
        return cls(model, document, device=device, name=str(name_or_path))

    @property
    def receptive_field(self) -> int:
        return self.model.receptive_field

    def lift(self, keypoints, camera: Camera, confidences=None, fps: float | None = None, layout: str = "h36m17",
             smooth_2d: str | None = None, smooth_3d: str | None = None, flip_test: bool = False,
             chunk: int = 8192, refine: bool | RefineConfig = True, progress: bool | str = False,
             floor: Floor = FLAT_FLOOR) -> LiftResult | list[LiftResult]:
        """Lift one person's pixels (T, J, 2) seen by ``camera``; (B, T, J, 2) lifts B sequences.

        Args:
            keypoints: pixels (u, v) in ``layout`` (h36m17, coco17, blazepose33, body25, ...); NaN = missing.
            confidences: optional (T, J) scores (0: missing); fps: the input's frame rate (default: the model's, 60).
            smooth_2d / smooth_3d: ``"savgol"`` or ``"one-euro"`` on the input pixels / output joints.
            refine: move the person along their rays so the feet rest on the ``floor``, one body size (``ray3d.refine``;
                a ``RefineConfig`` sets its uncertainties); False keeps the network's (either has its uncertainty).
            progress: a progress bar over the frames (a string labels it) for sequences longer than a chunk.
        """
        if fps is not None:
            temporal.check_frame_rate(fps, "lift")
        keypoints = np.asarray(keypoints, dtype=np.float64)
        if keypoints.ndim == 4:
            scores = [None] * len(keypoints) if confidences is None else confidences
            return [self.lift(k, camera, c, fps, layout, smooth_2d, smooth_3d, flip_test, chunk, refine, progress,
                              floor) for k, c in zip(keypoints, scores)]
        skeleton = layout_skeleton(layout)
        keypoints, confidences = checked_keypoints(keypoints, confidences, skeleton, ("frames",))
        if len(keypoints) == 0:
            raise InputError("keypoints: no frames")
        _check_in_image(keypoints, camera)
        h36m_pixels, h36m_found = convert_keypoints(keypoints, skeleton, confidences)
        _check_feet_below_horizon(h36m_pixels, h36m_found, camera)
        inputs = self._input_skeleton(skeleton)
        pixels, found = convert_keypoints(keypoints, skeleton, confidences, inputs)
        scores = model_confidences(keypoints, skeleton, confidences, inputs)
        never_seen = ~found.any(axis=0)
        if never_seen[0]:
            raise InputError(f"keypoints: the root ({inputs.joint_names[0]}, or both hips) is missing in every frame "
                             "(NaN or confidence 0): there is nothing to place the person by")
        input_fps = fps or MODEL_FPS
        seen_pixels = temporal.fill_missing(pixels, ~found)
        pixels = temporal.smooth(stand_in_for_unseen(seen_pixels, never_seen, inputs), smooth_2d, input_fps)
        resampled = temporal.needs_resampling(input_fps, MODEL_FPS)
        model_pixels, model_scores = ((temporal.resample(pixels, input_fps, MODEL_FPS),
                                       temporal.resample(scores, input_fps, MODEL_FPS)) if resampled else (pixels, scores))
        joints = self._lift_pixels(model_pixels, camera, flip_test, chunk, progress, model_scores)
        if resampled:
            joints = temporal.resample_back(joints, MODEL_FPS, input_fps, len(pixels))
        config = refine if isinstance(refine, RefineConfig) else RefineConfig.for_model(self.document)
        if refine:
            measured = np.where(never_seen[None, :, None], np.nan, pixels)  # a stand-in is no measurement
            joints, refined = refine_track(joints, camera, input_fps, joint_directions(camera, measured, inputs),
                                           temporal.seen_frames(~h36m_found), config,
                                           feet_seen=h36m_found[:, list(ANKLES)].any(axis=1), floor=floor)
            refinement, position_sd = refined.summary(), refined.position_sd_m
        else:
            refinement, position_sd = None, network_position_sd(joints, camera, config)
        joints = temporal.smooth(joints, smooth_3d, input_fps)
        return LiftResult(joints, ~h36m_found, input_fps, np.arange(len(joints)), refinement=refinement,
                          position_sd=position_sd)

    def _input_skeleton(self, skeleton: Skeleton) -> Skeleton:
        """The model's input layout, after checking that keypoints of ``skeleton`` give its joints."""
        inputs = self.model.config.input_skeleton
        try:
            conversion_matrix(skeleton.name, inputs.name)
        except InputError:
            raise InputError(f"keypoints: model {self.name} reads {inputs.name} joints, which {skeleton.name} keypoints "
                             "do not have; lift them with a model of H36M-17 input such as ray3d",
                             arguments=("checkpoint",)) from None
        return inputs

    def lift_tracks(self, tracks: dict, camera: Camera, layout: str = "h36m17", fps: float | None = None,
                    progress: bool = False, **options) -> LiftedTracks:
        """Several people: {track id: ``TrackDetections`` or (frame indices (N,), keypoints (N, J, 2)[,
        confidences (N, J)])} -> {track id: LiftResult} in one world frame; ``options`` as for ``lift``. Frames a
        track skips are filled in like missing joints. A track that cannot be lifted (say, its root never seen)
        is left out and named in the result's ``unliftable`` with why; only when no track can be lifted is that
        an error."""
        results, failures = LiftedTracks(), {}
        for track, entry in tracks.items():
            span, pixels, confidences = TrackDetections(*entry).dense()
            try:
                result = self.lift(pixels, camera, confidences, fps, layout,
                                   progress=f"track {track}" if progress else False, **options)
            except InputError as err:
                failures[track] = err
                continue
            results[track] = dataclasses.replace(result, frames=span)
        results.unliftable = {track: err.message for track, err in failures.items()}
        if not results and len(failures) == 1:
            raise next(iter(failures.values()))
        if not results:
            raise InputError("no track could be lifted: " + "; ".join(
                f"track {track}: {why}" for track, why in results.unliftable.items()))
        return results

    def lift_keypoints(self, keypoints: Keypoints, camera: Camera, options: LiftOptions = LiftOptions(),
                       progress: bool = False) -> World:
        """Every track of a keypoint file (``ray3d.io.keypoints.read_keypoints``) lifted into one world frame
        (the frame ``options`` name); tracks that cannot be lifted are named in ``World.unliftable``."""
        try:
            tracks = self.lift_tracks(keypoints.by_track(), camera, keypoints.layout, keypoints.fps, progress,
                                      **options.lift_arguments())
        except InputError as err:  # name the file the keypoints came from
            raise InputError(f"{keypoints.path or keypoints.source}: {err.message}", err.arguments) from None
        return World(tracks, camera, self.name, unliftable=tracks.unliftable).in_frame(options.frame)

    @torch.no_grad()
    def _lift_pixels(self, pixels: np.ndarray, camera: Camera, flip_test: bool, chunk: int,
                     progress: bool | str = False, confidences: np.ndarray | None = None) -> np.ndarray:
        """(T, J, 2) pixels of the model's input layout (gaps filled) and their (T, J) confidences -> (T, 17, 3)
        world joints."""
        rays = camera.pixels_to_rays(pixels, remove_roll=self.model.config.remove_roll)
        if not np.isfinite(rays).all():
            raise InputError(f"keypoints: some lie where camera {camera.name or ''}'s lens model cannot be inverted "
                             "(far outside the image?)")
        count = len(pixels)
        # Windows are gathered chunk by chunk (never all at once), which keeps memory bounded.
        index = temporal.sequence_window_indices(count, self.model.config.window)
        out = np.empty((count, 17, 3))
        bar = tqdm(total=count, unit="frame", desc=progress if isinstance(progress, str) else "lifting",
                   disable=not progress or count <= chunk)
        for start in range(0, count, chunk):
            part = index[start:start + chunk]
            out[start:start + len(part)] = self._lift_windows(pixels[part], rays[part], camera, flip_test,
                                                              None if confidences is None else confidences[part])
            bar.update(len(part))
        bar.close()
        return out

    @torch.no_grad()
    def _lift_windows(self, pixels: np.ndarray, rays: np.ndarray, camera: Camera, flip_test: bool,
                      confidences: np.ndarray | None = None) -> np.ndarray:
        """(N, F, J, 2) pixel, (N, F, J, 3) ray and optional (N, F, J) confidence windows of the model's input
        layout seen by ``camera`` -> (N, 17, 3) world joints."""
        cameras = CameraBatch.repeated(camera, len(pixels))
        batch = TensorBatch.from_arrays(pixels, rays, cameras, self.device, confidences)
        return predict_world(self.model, batch, cameras, flip_test).cpu().numpy()

    def stream(self, camera: Camera, layout: str = "h36m17", flip_test: bool = False) -> LiftStream:
        """Lift frame by frame as keypoints arrive (live use); see ``LiftStream``."""
        return LiftStream(self, camera, layout, flip_test)


def lift_file(keypoints_path: str | Path, camera: Camera, out: str | Path, lifter: Lifter | None = None,
              layout: str | None = None, fps: float | None = None, overwrite: bool = False,
              read_options: dict | None = None, options: LiftOptions = LiftOptions(),
              progress: bool = False) -> tuple[Keypoints, World]:
    """A keypoint file lifted into the world and written to ``out`` (.json/.csv/.npz/.trc/.bvh), as ``ray3d
    lift`` does, by ``lifter`` (default: the shipped model for the file's layout, ``Lifter.load(layout=...)``):
    ``layout`` and ``fps`` as the file states them unless given, ``read_options`` for the reader
    (``subject``, ``action``, ``camera_index`` of a VideoPose3D npz), ``options`` for the lifting (the output
    smoothed by Savitzky-Golay and written in the world frame unless they say otherwise). Returns what was read
    and what was written."""
    from ray3d.io.atomic import check_output, refuse_existing
    from ray3d.io.keypoints import read_keypoints
    from ray3d.io.world import check_world_output, write_world

    check_output(out, (keypoints_path,))
    check_world_output(out, options.frame)
    refuse_existing(out, overwrite)
    keypoints = read_keypoints(keypoints_path, layout, fps, **(read_options or {}))
    world = (lifter or Lifter.load(layout=keypoints.layout)).lift_keypoints(keypoints, camera, options, progress)
    write_world(out, world, overwrite=overwrite)
    return keypoints, world


class LiftStream:
    """Live lifting: ``push`` one frame's keypoints (J, 2) and get world joints (17, 3) back.

    A causal model (``ModelConfig.causal``, e.g. the ``ray3d-causal`` preset) answers for the frame just
    pushed. A centred model needs ``delay`` (half its window) future frames, so it answers for the frame pushed
    ``delay`` calls earlier (None until then) and ``flush()`` gives the last frames when the stream ends. The
    window starts by repeating the first frame and ends by repeating the last, as offline lifting does, so the
    outputs equal ``Lifter.lift`` on the whole sequence to float rounding (frames at the model's 60 fps, no
    smoothing, no refinement, which needs the whole track).

    A joint missing from a frame (NaN or confidence 0) keeps its last seen position (with confidence 0); one
    not seen yet takes its parent's, as a detector's miss is simulated in training.
    """

    def __init__(self, lifter: Lifter, camera: Camera, layout: str = "h36m17", flip_test: bool = False):
        config = lifter.model.config
        self.lifter, self.camera, self.skeleton, self.flip_test = lifter, camera, layout_skeleton(layout), flip_test
        self.frames = lifter.receptive_field
        self.delay = config.window.delay
        self.remove_roll = config.remove_roll
        self.inputs = lifter._input_skeleton(self.skeleton)  # the joints the model reads
        self._pixels: np.ndarray | None = None   # (F, J, 2) the current window, of the model's input layout
        self._rays: np.ndarray | None = None     # (F, J, 3)
        self._scores: np.ndarray | None = None   # (F, J) confidences
        self._last_seen = np.full((self.inputs.num_joints, 2), np.nan)
        self.pushed = 0       # frames pushed so far
        self.answered = 0     # frames answered so far

    def push(self, keypoints, confidences=None) -> np.ndarray | None:
        """One frame's pixels (J, 2) in the stream's layout -> world joints (17, 3) of frame ``answered``
        (the frame just pushed for a causal model), or None while a centred model waits for future frames."""
        self._append(*self._prepare(keypoints, confidences))
        self.pushed += 1
        return self._answer() if self.pushed > self.delay else None

    def flush(self) -> list[np.ndarray]:
        """The frames still unanswered at the end of the stream (none for a causal model)."""
        answers, window_end = [], self.pushed - 1  # the frame index the window ends at
        while self.answered < self.pushed:
            while window_end < self.answered + self.delay:
                self._append(self._pixels[-1], self._scores[-1])
                window_end += 1
            answers.append(self._answer())
        return answers

    def _prepare(self, keypoints, confidences) -> tuple[np.ndarray, np.ndarray]:
        keypoints, confidences = checked_keypoints(keypoints, confidences, self.skeleton)
        pixels, seen = convert_keypoints(keypoints, self.skeleton, confidences, self.inputs)
        scores = model_confidences(keypoints[None], self.skeleton, None if confidences is None else confidences[None],
                                   self.inputs)[0]
        self._last_seen = np.where(seen[:, None], pixels, self._last_seen)
        filled = self._last_seen.copy()
        if np.isnan(filled[0]).any():
            raise InputError("keypoints: the root (pelvis, or both hips) has not been seen yet")
        for joint, parent in enumerate(self.inputs.parents):  # parents come before their children
            if parent >= 0 and np.isnan(filled[joint]).any():
                filled[joint] = filled[parent]
        return filled, scores

    def _append(self, pixels: np.ndarray, scores: np.ndarray) -> None:
        rays = self.camera.pixels_to_rays(pixels, remove_roll=self.remove_roll)
        if not np.isfinite(rays).all():
            raise InputError(f"keypoints: some lie where camera {self.camera.name or ''}'s lens model cannot be "
                             "inverted (far outside the image?)")
        if self._pixels is None:
            self._pixels = np.repeat(pixels[None], self.frames, axis=0)
            self._rays = np.repeat(rays[None], self.frames, axis=0)
            self._scores = np.repeat(scores[None], self.frames, axis=0)
        else:
            self._pixels = np.concatenate([self._pixels[1:], pixels[None]])
            self._rays = np.concatenate([self._rays[1:], rays[None]])
            self._scores = np.concatenate([self._scores[1:], scores[None]])

    def _answer(self) -> np.ndarray:
        self.answered += 1
        return self.lifter._lift_windows(self._pixels[None], self._rays[None], self.camera, self.flip_test,
                                         self._scores[None])[0]
