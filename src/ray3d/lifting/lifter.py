"""``Lifter``: users' 2D keypoints and calibrated camera -> 3D joints in metres in the world frame.

Handles what real keypoints bring: other joint layouts (COCO-17, BlazePose-33, OpenPose BODY-25), missing joints
(NaN or confidence 0: interpolated in time and reported), other frame rates (resampled to the model's and back),
sequences shorter than the receptive field (edge-replicated), several people (each track lifted on its own into
one world frame), long sequences (in chunks), smoothing of the 2D input and 3D output, and a GPU when there is one.
"""

from __future__ import annotations

import dataclasses
import threading
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
from ray3d.io.keypoints import Keypoints, TrackDetections, read_keypoints
from ray3d.io.world import LiftResult, World
from ray3d.models.inference import BATCH_PER_GROUP, inference_network
from ray3d.models.network import LiftingNetwork, predict_world
from ray3d.models.precision import check_precision, with_precision
from ray3d.models.tensor_batch import TensorBatch
from ray3d.lifting.options import LiftOptions
from ray3d.refine import RefineConfig, joint_directions, network_position_sd, refine_track
from ray3d.lifting.inputs import (MODEL_FPS, check_feet_below_horizon, check_in_image, checked_keypoints,
                                 model_confidences, stand_in_for_unseen)
from ray3d.lifting.stream import LiftStream
from ray3d.skeleton import Skeleton, conversion_matrix, convert_keypoints, layout_skeleton

SMALL_BATCHES_BEFORE_TRACING = 3


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
        else:  # the TorchScript, ONNX Runtime and reduced-precision backends run on the CPU
            self.device, self.model = torch.device("cpu"), model
        self.precision = getattr(model, "precision", "fp32")
        # Eager torch spends a small batch's time in Python dispatch (the lite model: 0.7-0.8 ms for one window
        # against 0.4-0.6 ms traced): a lifter that keeps being given small batches (a stream, live) runs them
        # through a frozen TorchScript trace of the same network, made once. Ray-input models only: a
        # pixel-input trace is bound to one image width.
        self._small_batches, self._small_batch_runner, self._tracing = 0, None, threading.Lock()
        self._traceable = (isinstance(self.model, LiftingNetwork) and self.device.type == "cpu"
                           and self.model.config.input.endswith("rays"))

    @classmethod
    def load(cls, name_or_path: str | None = None, device: str | None = None, backend: str = "torch",
             image_width: float = 1000.0, layout: str = "h36m17", precision: str = "fp32") -> Lifter:
        """A shipped model by name (``ray3d``, ``ray3d-real``, ``videopose3d``, ...) or a checkpoint path; without
        one, the shipped model for keypoints of ``layout`` (``checkpoints.default_model``: ``ray3d`` for H36M-17,
        ``ray3d-real`` for a detector's layout).

        ``backend="torchscript"`` runs a frozen TorchScript trace on the CPU (lowest latency with torch alone:
        live use); ``backend="onnx"`` runs it with ONNX Runtime (``pip install 'ray3d[onnx]'``). Pixel-input
        models are then built for images ``image_width`` pixels wide.

        ``precision="bf16"`` or ``"int8"`` runs the network's hidden matrix products in that precision on the
        CPU (``models.precision``; its accuracy cost is in docs/RESULTS.md and ``ray3d evaluate --precision``).
        """
        check_precision(precision)
        name_or_path = name_or_path or default_model(layout)
        model, document = load_model(name_or_path)
        if precision != "fp32":
            if backend != "torch" or (device or "cpu") != "cpu":
                raise InputError(f"precision {precision!r} runs on the torch backend on the CPU; got backend "
                                 f"{backend!r}, device {device or 'cpu'!r}")
            return cls(with_precision(model, precision), document, name=str(name_or_path))
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
        check_in_image(keypoints, camera)
        h36m_pixels, h36m_found = convert_keypoints(keypoints, skeleton, confidences)
        check_feet_below_horizon(h36m_pixels, h36m_found, camera)
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
        config = refine if isinstance(refine, RefineConfig) else RefineConfig.for_model(self.document, skeleton)
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
        return predict_world(self._runner(len(pixels)), batch, cameras, flip_test).cpu().numpy()

    def _runner(self, windows: int):
        """What runs a batch of ``windows``: the network, or from the third small batch (below
        ``BATCH_PER_GROUP`` windows) on, its TorchScript trace."""
        if not self._traceable or windows >= BATCH_PER_GROUP:
            return self.model
        if self._small_batch_runner is None:
            self._small_batches += 1
            if self._small_batches >= SMALL_BATCHES_BEFORE_TRACING:
                self._trace_small_batches()
        return self._small_batch_runner or self.model

    def prepare_small_batches(self) -> None:
        """Make the small-batch trace now (about 0.2 s, holding the interpreter: a thread would not hide it)
        rather than on the third small batch: for a caller about to send small batches on a clock (``ray3d
        live``), before its frames flow."""
        self._trace_small_batches()

    def _trace_small_batches(self) -> None:
        # Not waiting for a trace another thread is making: meanwhile its small batches run the network itself.
        if not self._traceable or not self._tracing.acquire(blocking=False):
            return
        try:
            if self._small_batch_runner is None:
                from ray3d.models.backends import TorchScriptLiftingModel

                self._small_batch_runner = TorchScriptLiftingModel(self.model, batches=(2,))
        finally:
            self._tracing.release()

    def stream(self, camera: Camera, layout: str = "h36m17", flip_test: bool = False, fps: float | None = None,
               wait_for_future: bool = True) -> LiftStream:
        """Lift frame by frame as keypoints arrive (live use); see ``LiftStream``."""
        return LiftStream(self, camera, layout, flip_test, fps, wait_for_future)


def chosen_lifter(checkpoint: str | None = None, precision: str = "fp32", layout: str | None = None,
                  keypoints_path: str | Path | None = None) -> Lifter | None:
    """``checkpoint`` (or the shipped model for keypoints of ``layout``, else of the file ``keypoints_path``'s
    layout) in ``precision``; None when neither a checkpoint nor a reduced precision is asked for: then
    ``lift_file``, ``lift_video`` and ``run_live`` choose the shipped model for their input's layout themselves."""
    if not checkpoint and check_precision(precision) == "fp32":
        return None
    if not checkpoint and layout is None and keypoints_path is not None:
        layout = read_keypoints(keypoints_path).layout
    return Lifter.load(checkpoint, layout=layout or "h36m17", precision=precision)


def lift_file(keypoints_path: str | Path, camera: Camera, out: str | Path | None, lifter: Lifter | None = None,
              layout: str | None = None, fps: float | None = None, overwrite: bool = False,
              read_options: dict | None = None, options: LiftOptions = LiftOptions(),
              progress: bool = False) -> tuple[Keypoints, World]:
    """A keypoint file lifted into the world and written to ``out`` (.json/.csv/.npz/.trc/.bvh), as ``ray3d
    lift`` does, by ``lifter`` (default: the shipped model for the file's layout, ``Lifter.load(layout=...)``):
    ``layout`` and ``fps`` as the file states them unless given, ``read_options`` for the reader
    (``subject``, ``action``, ``camera_index`` of a VideoPose3D npz), ``options`` for the lifting (the output
    smoothed by Savitzky-Golay and written in the world frame unless they say otherwise). Returns what was read
    and what was written (``out`` None: lifted, not written)."""
    from ray3d.io.atomic import check_output, refuse_existing
    from ray3d.io.world import check_world_output, write_world

    if out is not None:
        check_output(out, (keypoints_path,))
        check_world_output(out, options.frame)
        refuse_existing(out, overwrite)
    keypoints = read_keypoints(keypoints_path, layout, fps, **(read_options or {}))
    world = (lifter or Lifter.load(layout=keypoints.layout)).lift_keypoints(keypoints, camera, options, progress)
    if out is not None:
        write_world(out, world, overwrite=overwrite)
    return keypoints, world
