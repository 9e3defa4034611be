"""Reduced precision for inference on the CPU: a network's hidden matrix products in bfloat16 (``bf16``) or
int8 (``int8``); everything between them, and its input and output layers, in float32.

- ``bf16``: each hidden linear layer's weights stored as bfloat16, its input rounded to bfloat16 and its output
  widened back (oneDNN's bf16 kernels: about 2.4x the fp32 product rate on a CPU with AVX512-BF16 or AMX;
  emulated, and slower, on one without: ``bf16_native``);
- ``int8``: each hidden ``nn.Linear`` (the temporal convolutions included) dynamically quantized: weights int8
  per output channel, its input int8 per tensor scaled at run time, float32 out (torch's quantized linear
  kernels; VNNI where the CPU has it). The stacked layers of the small-batch path
  (``models.inference.StackedLinear``, below ``BATCH_PER_GROUP`` windows, where the time is dispatch rather
  than arithmetic) keep float32.

Kept in float32: the input layers (those that read the rays and their encodings: bf16 keeps 8 significant bits,
and a ray coordinate rounded to them moves by up to 0.2 % of its value, much of a body's extent in the image when
the person is far away), the output layers (the last linear map of every decoder and head: a log depth rounded
to bf16 is 0.4 % of the distance, 4 cm at 10 m), the residual sums and activations between layers (rounding
them too cost ray3d-real 49 mm Abs-MPJPE on far-test), and the attention blocks (torch's fused kernels read
their weights directly). What each precision costs is measured, not assumed: docs/RESULTS.md, "Speed past
fp32", and ``ray3d evaluate --precision``.
"""

from __future__ import annotations

import copy
import warnings

import torch
from torch import nn

from ray3d.errors import InputError
from ray3d.models.blocks import FrameGroupLinear, stack_frames
from ray3d.models.inference import BATCH_PER_GROUP, InferenceOnly, StackedLinear, StackedRIEBranch, inference_network
from ray3d.models.network import predict_with_flip
from ray3d.models.tensor_batch import TensorBatch

PRECISIONS = ("fp32", "bf16", "int8")
# Modules whose fused kernels read their linear layers' weights directly: their layers keep float32.
_FUSED = (nn.MultiheadAttention, nn.TransformerEncoderLayer)


def check_precision(precision: str) -> str:
    if precision not in PRECISIONS:
        raise InputError(f"precision: {precision!r} is not one of {', '.join(PRECISIONS)}")
    return precision


def bf16_native() -> bool:
    """Whether this CPU computes bfloat16 products in hardware (oneDNN's check: AVX512-BF16 or AMX)."""
    return bool(torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported())


class Bfloat16Products(nn.Module):
    """A linear layer whose products run in bfloat16 (weights stored so, its input rounded to it) and whose
    output is float32 again: between layers, the residual sums and activations keep float32's precision."""

    def __init__(self, layer: nn.Module):
        super().__init__()
        self.layer = layer.to(torch.bfloat16)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.layer(x.to(torch.bfloat16)).float()


class Int8Products(nn.Module):
    """A linear layer dynamically quantized: weights int8 per output channel, its input int8 per tensor (scaled
    at run time), float32 out. A ``FrameGroupLinear`` keeps its frame stacking."""

    def __init__(self, layer: nn.Linear):
        super().__init__()
        plain = nn.Linear(layer.in_features, layer.out_features, bias=layer.bias is not None)
        plain.load_state_dict(layer.state_dict())
        plain.qconfig = torch.ao.quantization.per_channel_dynamic_qconfig
        with warnings.catch_warnings():  # torch 2.13 calls its eager quantization API deprecated
            warnings.simplefilter("ignore")
            self.linear = torch.ao.nn.quantized.dynamic.Linear.from_float(plain)
        self.kernel = layer.kernel if isinstance(layer, FrameGroupLinear) else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.linear(x if self.kernel is None else stack_frames(x, self.kernel))


def output_layer_names(network: nn.Module) -> list[str]:
    """The qualified names of ``network``'s output layers: each ``nn.Sequential`` that ends in a linear map (the
    decoders and heads of ``blocks.mlp``; hidden units end in an activation), and the stacked decoders' output
    layer of the small-batch path."""
    names = []
    for name, module in network.named_modules():
        prefix = f"{name}." if name else ""
        if isinstance(module, nn.Sequential) and len(module) and isinstance(module[-1], nn.Linear):
            names.append(f"{prefix}{len(module) - 1}")
        elif isinstance(module, StackedRIEBranch) and hasattr(module, "decode_out"):
            names.append(f"{prefix}decode_out")
    return names


def input_layer_names(network: nn.Module, example_batches) -> list[str]:
    """The qualified names of the linear layers that read ``network``'s float32 input (the rays, their
    encodings, the camera's parameters) rather than another layer's output: under bf16 autocast every linear
    layer's output is bfloat16, so these are the layers whose input is still float32, found by running
    ``network`` on ``example_batches`` (both its paths: stacked and per group)."""
    layers = {name: module for name, module in network.named_modules()
              if isinstance(module, (nn.Linear, StackedLinear))}
    reading_float32: set[str] = set()

    def hook(name):
        def record(_module, inputs):
            if any(isinstance(x, torch.Tensor) and x.dtype == torch.float32 for x in inputs):
                reading_float32.add(name)
        return record

    handles = [module.register_forward_pre_hook(hook(name)) for name, module in layers.items()]
    try:
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16):
            for batch in example_batches:
                network(batch)
    finally:
        for handle in handles:
            handle.remove()
    return sorted(reading_float32)


def _replace(network: nn.Module, name: str, layer: nn.Module) -> None:
    parent, _, child = name.rpartition(".")
    setattr(network.get_submodule(parent) if parent else network, child, layer)


class ReducedPrecisionNetwork(InferenceOnly):
    """A ``LiftingNetwork`` in its inference form, run in ``precision`` ("bf16" or "int8"); the same interface
    (``config``, ``receptive_field``, ``predict``, ``to_world``, ...) as the float32 network."""

    cannot_train = "a reduced-precision network cannot be trained"

    def __init__(self, model: nn.Module, precision: str):
        super().__init__()
        if check_precision(precision) == "fp32":
            raise ValueError("ReducedPrecisionNetwork: fp32 is the network itself")
        self.precision = precision
        with torch.no_grad():
            network = copy.deepcopy(inference_network(model)).cpu()  # the caller's model stays where it is
            examples = [TensorBatch.example(network.receptive_field, network.skeleton.num_joints, size)
                        for size in (1, BATCH_PER_GROUP)]
            kept = set(output_layer_names(network)) | set(input_layer_names(network, examples))
            kept |= {f"{name}.{inner}" for name, module in network.named_modules() if isinstance(module, _FUSED)
                     for inner, _ in module.named_modules()}
            layers = [name for name, module in network.named_modules()
                      if isinstance(module, (nn.Linear, StackedLinear)) and name not in kept]
            for name in layers:
                layer = network.get_submodule(name)
                if precision == "bf16":
                    _replace(network, name, Bfloat16Products(layer))
                elif isinstance(layer, nn.Linear):
                    _replace(network, name, Int8Products(layer))
        self.network = network
        self.config, self.receptive_field = network.config, network.receptive_field
        self.skeleton, self.output_skeleton = network.skeleton, network.output_skeleton
        self.inference_form = True

    def forward(self, batch):
        with torch.no_grad():
            return self.network(batch)

    def predict(self, batch, flip_test: bool = False):
        return predict_with_flip(self, self.config, batch, flip_test)

    def to_world(self, points, cameras, camera_params):
        return self.network.to_world(points, cameras, camera_params)


def with_precision(model: nn.Module, precision: str = "fp32") -> nn.Module:
    """``model``'s inference form in ``precision``: the network itself for "fp32", else a
    ``ReducedPrecisionNetwork`` (CPU)."""
    if check_precision(precision) == "fp32":
        return inference_network(model)
    return ReducedPrecisionNetwork(model, precision)
