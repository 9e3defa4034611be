"""``ModelRunner``: a trained network ready to run on windows of keypoints, whatever runs it (torch on the CPU or a
GPU, a TorchScript trace, ONNX Runtime, reduced precision); what ``Lifter`` and ``LiftStream`` stand on."""

from __future__ import annotations

import threading

import numpy as np
import torch

from ray3d import temporal
from ray3d.checkpoints import default_model, load_model
from ray3d.console import progress_bar
from ray3d.errors import InputError
from ray3d.geometry import Camera, CameraBatch
from ray3d.lifting.inputs import MODEL_FPS, PreparedTrack, camera_rays
from ray3d.models.backends import OnnxLiftingModel, TorchScriptLiftingModel
from ray3d.models.inference import BATCH_PER_GROUP, inference_network
from ray3d.models.network import LiftingNetwork, predict_world
from ray3d.models.precision import check_precision, with_precision
from ray3d.models.tensor_batch import TensorBatch
from ray3d.skeleton import Skeleton, conversion_matrix

SMALL_BATCHES_BEFORE_TRACING = 3


class ModelRunner:
    """A trained network (``model``, with the ``document`` saved beside its weights) and what runs it: windows of
    the model's input layout in, world joints out. ``ModelRunner.load()`` gives the shipped Ray3D weights."""

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
        # against 0.4-0.6 ms traced): a runner that keeps being given small batches (a stream, live) runs them
        # through a frozen TorchScript trace of the same network, made once. Ray-input models only: a
        # pixel-input trace is bound to one image width.
        self._small_batches, self._small_batch_runner, self._tracing = 0, None, threading.Lock()
        self._traceable = (isinstance(self.model, LiftingNetwork) and self.device.type == "cpu"
                           and self.model.config.input.endswith("rays"))

    @classmethod
    def load(cls, name_or_path: str | None = None, device: str | None = None, backend: str = "torch",
             image_width: float = 1000.0, layout: str = "h36m17", precision: str = "fp32") -> ModelRunner:
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
        backends = {"torchscript": TorchScriptLiftingModel, "onnx": OnnxLiftingModel}
        if backend in backends:
            return cls(backends[backend](model, image_width), document, name=str(name_or_path))
        if backend != "torch":
            raise InputError(f"unknown backend {backend!r}; 'torch', 'torchscript' or 'onnx'")
        return cls(model, document, device=device, name=str(name_or_path))

    @property
    def receptive_field(self) -> int:
        return self.model.receptive_field

    def input_skeleton(self, skeleton: Skeleton) -> Skeleton:
        """The model's input layout, after checking that keypoints of ``skeleton`` give its joints."""
        inputs = self.model.config.input_skeleton
        try:
            conversion_matrix(skeleton.name, inputs.name)
        except InputError:
            raise InputError(f"keypoints: model {self.name} reads {inputs.name} joints, which {skeleton.name} "
                             "keypoints do not have; lift them with a model of H36M-17 input such as ray3d",
                             arguments=("checkpoint",)) from None
        return inputs

    def network(self, prepared: PreparedTrack, camera: Camera, flip_test: bool, chunk: int,
                progress: bool | str) -> np.ndarray:
        """(T, 17, 3) world joints of a prepared track as the network puts them, at the track's rate."""
        fps, pixels, scores = prepared.fps, prepared.pixels, prepared.scores
        resampled = temporal.needs_resampling(fps, MODEL_FPS)
        if resampled:
            pixels, scores = temporal.resample(pixels, fps, MODEL_FPS), temporal.resample(scores, fps, MODEL_FPS)
        joints = self._lift_sequence(pixels, camera, flip_test, chunk, progress, scores)
        return temporal.resample_back(joints, MODEL_FPS, fps, len(prepared.pixels)) if resampled else joints

    @torch.no_grad()
    def _lift_sequence(self, pixels: np.ndarray, camera: Camera, flip_test: bool, chunk: int,
                       progress: bool | str, confidences: np.ndarray) -> np.ndarray:
        """(T, J, 2) pixels of the model's input layout (gaps filled) and their (T, J) confidences at the model's
        rate -> (T, 17, 3) world joints, ``chunk`` windows per network call."""
        rays = camera_rays(camera, pixels, self.model.config.remove_roll)
        count = len(pixels)
        # Windows are gathered chunk by chunk (never all at once), which keeps memory bounded.
        index = temporal.sequence_window_indices(count, self.model.config.window)
        out = np.empty((count, 17, 3))
        bar = progress_bar(total=count, unit="frame", desc=progress if isinstance(progress, str) else "lifting",
                           shown=bool(progress) and count > chunk)
        for start in range(0, count, chunk):
            part = index[start:start + chunk]
            out[start:start + len(part)] = self.lift_windows(pixels[part], rays[part], camera, flip_test,
                                                              confidences[part])
            bar.update(len(part))
        bar.close()
        return out

    @torch.no_grad()
    def lift_windows(self, pixels: np.ndarray, rays: np.ndarray, camera: Camera, flip_test: bool,
                     confidences: np.ndarray | None = None) -> np.ndarray:
        """(N, F, J, 2) pixel, (N, F, J, 3) ray and optional (N, F, J) confidence windows of the model's input
        layout seen by ``camera`` -> (N, 17, 3) world joints."""
        cameras = CameraBatch.repeated(camera, len(pixels))
        batch = TensorBatch.from_arrays(pixels, rays, cameras, self.device, confidences)
        return predict_world(self._network_for(len(pixels)), batch, cameras, flip_test).cpu().numpy()

    def _network_for(self, windows: int):
        """What runs a batch of ``windows``: the network, or from the third small batch (below
        ``BATCH_PER_GROUP`` windows) on, its TorchScript trace."""
        if not self._traceable or windows >= BATCH_PER_GROUP:
            return self.model
        if self._small_batch_runner is None:
            self._small_batches += 1
            if self._small_batches >= SMALL_BATCHES_BEFORE_TRACING:
                self.prepare_small_batches()
        return self._small_batch_runner or self.model

    def prepare_small_batches(self) -> None:
        """Make the small-batch trace now (about 0.2 s, holding the interpreter: a thread would not hide it)
        rather than on the third small batch: for a caller about to send small batches on a clock (``ray3d
        live``), before its frames flow."""
        # Not waiting for a trace another thread is making: meanwhile its small batches run the network itself.
        if not self._traceable or not self._tracing.acquire(blocking=False):
            return
        try:
            if self._small_batch_runner is None:
                self._small_batch_runner = TorchScriptLiftingModel(self.model, batches=(2,))
        finally:
            self._tracing.release()
