"""Building blocks: strided temporal convolutions with computed receptive field, MLPs, camera embedding."""

from __future__ import annotations

import math

import torch
from torch import nn

from ray3d.temporal import target_frame


def receptive_field(kernels: tuple[int, ...]) -> int:
    """Frames seen by a stack of stride-equals-kernel convolutions: the product of the kernel widths."""
    return math.prod(kernels)


def stack_frames(x: torch.Tensor, kernel: int) -> torch.Tensor:
    """(B, L, C) -> (B, L / kernel, kernel * C): each ``kernel`` consecutive frames side by side."""
    batch, length, channels = x.shape
    return x.reshape(batch, length // kernel, kernel * channels)


class FrameGroupLinear(nn.Linear):
    """A width-k, stride-k temporal convolution, channels last: (B, L, C_in) -> (B, L / k, C_out), computed as
    one Linear over each k consecutive frames stacked. The same maths as ``nn.Conv1d(kernel=k, stride=k)``, but
    the GEMM runs through ``nn.Linear`` (MKL), which is faster than the convolution path on the CPUs measured
    (docs/RESULTS.md). Older checkpoints' Conv1d weights (C_out, C_in, k) are converted when loaded."""

    def __init__(self, in_channels: int, out_channels: int, kernel: int):
        super().__init__(kernel * in_channels, out_channels, bias=False)
        self.kernel = kernel

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(stack_frames(x, self.kernel))

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs):
        weight = state_dict.get(prefix + "weight")
        if weight is not None and weight.dim() == 3:  # Conv1d layout: (out, in, k) -> (out, k * in)
            state_dict[prefix + "weight"] = weight.permute(0, 2, 1).reshape(weight.shape[0], -1)
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)


class BatchNorm(nn.BatchNorm1d):
    """``BatchNorm1d`` over the last axis of (..., C): statistics over every other axis, as for (B, C, L).

    In data-parallel training (torchrun, several processes) the statistics are those of the whole batch, summed
    over the processes, so N processes with batch B train as one process with batch N x B. torch's own
    ``SyncBatchNorm`` does this on GPUs only; this one also works with gloo on CPUs.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        flat = x.reshape(-1, x.shape[-1])
        if not (self.training and torch.distributed.is_available() and torch.distributed.is_initialized()
                and torch.distributed.get_world_size() > 1):
            return super().forward(flat).reshape(x.shape)
        from torch.distributed.nn.functional import all_reduce  # differentiable: gradients see the global mean

        count = flat.shape[0] * torch.distributed.get_world_size()
        mean = all_reduce(flat.sum(0)) / count
        centred = flat - mean
        variance = all_reduce(centred.square().sum(0)) / count  # two passes: no cancellation in float32
        with torch.no_grad():
            self.num_batches_tracked += 1
            self.running_mean.lerp_(mean, self.momentum)
            self.running_var.lerp_(variance * count / max(count - 1, 1), self.momentum)
        normalised = centred * torch.rsqrt(variance + self.eps)
        return (normalised * self.weight + self.bias).reshape(x.shape)


class Dropout(nn.Module):
    """``nn.Dropout`` whose mask is drawn as 16 random bits per element: torch's CPU Bernoulli sampler is about
    4x slower than drawing the bits and took a quarter of a lite training step (docs/RESULTS.md, "Speed at every
    size"). The drop probability is ``p`` rounded to a multiple of 1/65536; kept values are scaled by the exact
    inverse of the keep probability, so the expectation is unchanged. An identity in eval mode."""

    _LEVELS = 1 << 16

    def __init__(self, p: float):
        super().__init__()
        if not 0.0 <= p < 1.0:
            raise ValueError(f"dropout probability must be in [0, 1), got {p}")
        self.p = p
        self.dropped_levels = round(p * self._LEVELS)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.dropped_levels == 0:
            return x
        count = x.numel()
        words = torch.randint(-2**63, 2**63 - 1, ((count + 3) // 4,), dtype=torch.int64, device=x.device)
        bits = words.view(torch.int16)[:count].view(x.shape)  # uniform over [-32768, 32767]
        keep = bits >= self.dropped_levels - self._LEVELS // 2
        return x * keep.to(x.dtype).mul_(self._LEVELS / (self._LEVELS - self.dropped_levels))

    def extra_repr(self) -> str:
        return f"p={self.p}"


def _conv_unit(in_channels: int, out_channels: int, kernel: int, dropout: float) -> nn.Sequential:
    return nn.Sequential(FrameGroupLinear(in_channels, out_channels, kernel),
                         BatchNorm(out_channels), nn.LeakyReLU(0.2), Dropout(dropout))


class TemporalEncoder(nn.Module):
    """(B, F, features) -> (B, channels): an expanding conv of width kernels[0], then one residual block per
    further kernel (a width-k stride-k conv and a 1x1 conv), each shortening time by k, down to one frame.

    The residual path takes the centre frame of every k-frame stride window (the last one when ``causal``),
    so the output is aligned with the frame the network predicts.
    """

    def __init__(self, in_features: int, channels: int, kernels: tuple[int, ...], dropout: float,
                 causal: bool = False):
        super().__init__()
        self.kernels = tuple(kernels)
        self.causal = causal
        self.receptive_field = receptive_field(self.kernels)
        self.expand = _conv_unit(in_features, channels, self.kernels[0], dropout)
        self.blocks = nn.ModuleList(
            nn.Sequential(_conv_unit(channels, channels, k, dropout), _conv_unit(channels, channels, 1, dropout))
            for k in self.kernels[1:])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[1] != self.receptive_field:
            raise ValueError(f"TemporalEncoder: expected {self.receptive_field} frames, got {x.shape[1]}")
        x = self.expand(x)
        for k, block in zip(self.kernels[1:], self.blocks):
            x = x[:, target_frame(k, self.causal)::k] + block(x)
        return x[:, 0]


def mlp(in_features: int, hidden: int, out_features: int, depth: int, dropout: float) -> nn.Sequential:
    """``depth`` hidden Linear-BN-LeakyReLU-Dropout layers, then a linear output layer."""
    layers: list[nn.Module] = []
    width = in_features
    for _ in range(depth):
        layers += [nn.Linear(width, hidden, bias=False), BatchNorm(hidden), nn.LeakyReLU(0.2), Dropout(dropout)]
        width = hidden
    layers.append(nn.Linear(width, out_features))
    return nn.Sequential(*layers)


class CameraEmbedding(nn.Module):
    """(B, 2) camera (height m, pitch rad) -> (B, 64): the paper's Linear(2, 32) and Linear(32, 64) MLP."""

    out_features = 64

    def __init__(self, dropout: float):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(2, 32), BatchNorm(32), nn.LeakyReLU(0.2), Dropout(dropout),
            nn.Linear(32, self.out_features), BatchNorm(self.out_features), nn.LeakyReLU(0.2), Dropout(dropout))

    def forward(self, camera_params: torch.Tensor) -> torch.Tensor:
        return self.net(camera_params)
