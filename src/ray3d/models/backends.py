"""Inference backends with the ``LiftingNetwork`` interface (``predict``, ``to_world``, ``config``): a frozen
TorchScript trace (no Python per layer: the low-latency path with torch alone), and ONNX export with an ONNX
Runtime backend (optional extra: ``pip install ray3d[onnx]``). Both run the network's inference form
(``models.inference``: batch norms folded, joint groups stacked)."""

from __future__ import annotations

import importlib.util
import io
import warnings
from pathlib import Path

import numpy as np
import torch

from ray3d.errors import InputError
from ray3d.geometry import CameraBatch
from ray3d.models.inference import BATCH_PER_GROUP, inference_network
from ray3d.models.network import LiftingNetwork, frame_to_world, predict_with_flip
from ray3d.models.tensor_batch import TensorBatch

INPUT_NAMES = ("pixels", "rays", "camera_params", "intrinsics", "roll", "confidences")
OUTPUT_NAMES = ("pose", "root")


class _TensorInputs(torch.nn.Module):
    """The network with plain tensor inputs, as ONNX needs them."""

    def __init__(self, model: LiftingNetwork, image_width: float):
        super().__init__()
        self.model, self.image_width = model, image_width

    def forward(self, pixels, rays, camera_params, intrinsics, roll, confidences):
        return self.model(TensorBatch(pixels, rays, camera_params, intrinsics, roll, self.image_width, confidences))


def _example_inputs(model: LiftingNetwork, image_width: float, batch: int = 2) -> tuple[torch.Tensor, ...]:
    example = TensorBatch.example(model.receptive_field, model.skeleton.num_joints, batch, image_width=image_width)
    return tuple(getattr(example, name) for name in INPUT_NAMES)


class _Backend:
    """What every backend shares: flip-test prediction and the way back to the world."""

    def __init__(self, model: LiftingNetwork, image_width: float):
        self.config, self.receptive_field = model.config, model.receptive_field
        self.skeleton, self.output_skeleton = model.skeleton, model.output_skeleton
        self.image_width = image_width

    def _check_width(self, batch: TensorBatch) -> None:
        """Pixel-input models baked the image width in; ray-input models never read it."""
        if self.config.input.startswith("pixels") and batch.image_width != self.image_width:
            raise InputError(f"this {type(self).__name__} was built for {self.image_width:g}-pixel-wide images, got "
                             f"{batch.image_width:g}")

    def predict(self, batch: TensorBatch, flip_test: bool = False):
        return predict_with_flip(self, self.config, batch, flip_test)

    def to_world(self, points: torch.Tensor, cameras: CameraBatch, camera_params: torch.Tensor) -> torch.Tensor:
        return frame_to_world(points, self.config.output_frame, cameras, camera_params, self.config.remove_roll)


class TorchScriptLiftingModel(_Backend):
    """A ``LiftingNetwork``'s inference form traced and frozen by TorchScript (CPU). A trace keeps the path its
    example took, so the form is traced twice: at a small batch (the stacked groups: latency) and at a large
    one (per-group layers: throughput); each call runs the trace for its batch size. ``batches=(2,)`` traces
    the small-batch path only (for a caller that sends it nothing else)."""

    def __init__(self, model: LiftingNetwork, image_width: float = 1000.0,
                 batches: tuple[int, ...] = (2, BATCH_PER_GROUP)):
        super().__init__(model, image_width)
        network = _TensorInputs(inference_network(model.cpu()), image_width).eval()
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore", category=torch.jit.TracerWarning)
            warnings.simplefilter("ignore", category=DeprecationWarning)
            self.modules = {batch: torch.jit.freeze(torch.jit.trace(
                network, _example_inputs(model, image_width, batch), check_trace=False))
                for batch in batches}

    def __call__(self, batch: TensorBatch) -> tuple[torch.Tensor, torch.Tensor]:
        self._check_width(batch)
        module = self.modules[BATCH_PER_GROUP if len(batch.rays) >= BATCH_PER_GROUP and BATCH_PER_GROUP in self.modules
                              else 2]
        with torch.no_grad():
            return module(*(getattr(batch, n).cpu() for n in INPUT_NAMES))


def export_onnx(model: LiftingNetwork, target: str | Path | io.BytesIO, image_width: float = 1000.0) -> None:
    """Write ``model`` as ONNX (batch axis dynamic). Pixel-input models bake in ``image_width``."""
    if importlib.util.find_spec("onnx") is None:
        raise InputError("ONNX export needs the onnx extra: pip install 'ray3d[onnx]'")
    model = inference_network(model.cpu())  # traced at a small batch: the stacked groups, for latency
    example = _example_inputs(model, image_width)
    # The trace warns about the window-length checks (the receptive field is fixed by design) and about the
    # TorchScript exporter, chosen because the torch.export one needs onnxscript as well. Transformer layers
    # are exported as their parts: ONNX has no operator for torch's fused inference kernel.
    # It also says it cannot constant-fold the residuals' strided slices, which are not constants anyway.
    fastpath = torch.backends.mha.get_fastpath_enabled()
    torch.backends.mha.set_fastpath_enabled(False)
    try:
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore", category=torch.jit.TracerWarning)
            warnings.simplefilter("ignore", category=DeprecationWarning)
            warnings.filterwarnings("ignore", message="Constant folding - Only steps=1")
            torch.onnx.export(_TensorInputs(model, image_width).eval(), example, target, input_names=list(INPUT_NAMES),
                              output_names=list(OUTPUT_NAMES),
                              dynamic_axes={n: {0: "batch"} for n in INPUT_NAMES + OUTPUT_NAMES},
                              opset_version=17, dynamo=False)
    finally:
        torch.backends.mha.set_fastpath_enabled(fastpath)


class OnnxLiftingModel(_Backend):
    """A ``LiftingNetwork`` run by ONNX Runtime."""

    def __init__(self, model: LiftingNetwork, image_width: float = 1000.0, threads: int | None = None):
        try:
            import onnxruntime
        except ImportError:
            raise InputError("the ONNX backend needs onnxruntime: pip install 'ray3d[onnx]'") from None
        super().__init__(model, image_width)
        buffer = io.BytesIO()
        export_onnx(model, buffer, image_width)
        options = onnxruntime.SessionOptions()
        if threads:
            options.intra_op_num_threads = threads
        self.session = onnxruntime.InferenceSession(buffer.getvalue(), options, providers=["CPUExecutionProvider"])
        self.inputs = [i.name for i in self.session.get_inputs()]  # the exporter drops inputs a model never reads

    def __call__(self, batch: TensorBatch) -> tuple[torch.Tensor, torch.Tensor]:
        self._check_width(batch)
        values = {n: getattr(batch, n).detach().cpu().numpy().astype(np.float32) for n in self.inputs}
        pose, root = self.session.run(list(OUTPUT_NAMES), values)
        return torch.from_numpy(pose), torch.from_numpy(root)
