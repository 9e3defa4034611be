"""A PoseFormer-style backbone (Zheng et al., ICCV 2021), written from the paper's description: a spatial
transformer over the joints of each frame (each joint's 2D input embedded, plus a learned joint-position
embedding), then a temporal transformer over the frames (each frame the concatenation of its joints' spatial
features, plus a learned frame-position embedding), then a learned weighted mean over the frames. No dropout inside the
transformers, as in the paper (it also costs more than the attention on a CPU); the heads after it keep theirs."""

from __future__ import annotations

import torch
from torch import nn

TEMPORAL_HEADS = 8        # as in the paper
SPATIAL_HEAD_FEATURES = 8  # a spatial head per 8 features of a joint: 1-feature heads are slow and no better


def _transformer(width: int, layers: int, heads: int) -> nn.TransformerEncoder:
    """Pre-norm blocks (LayerNorm, multi-head self-attention, LayerNorm, GELU MLP of twice the width)."""
    block = nn.TransformerEncoderLayer(width, heads, 2 * width, 0.0, activation="gelu", batch_first=True,
                                       norm_first=True)
    return nn.TransformerEncoder(block, layers, enable_nested_tensor=False)


class PoseTransformer(nn.Module):
    """(B, F, J, C) per-joint inputs, optional (B, F, J) per-joint extra features -> (B, J * width).

    ``width`` is each joint's spatial feature size; the temporal transformer works on ``J * width`` features per
    frame. The window's frames all count, weighted by learned per-frame weights, so a window of past frames
    (causal) needs nothing different: which frame is predicted is learned from the targets.
    """

    def __init__(self, joints: int, in_channels: int, width: int, layers: int, frames: int,
                 extra_per_joint: int = 0):
        super().__init__()
        if width % SPATIAL_HEAD_FEATURES:
            raise ValueError(f"PoseTransformer: width {width} is not a multiple of {SPATIAL_HEAD_FEATURES}")
        self.receptive_field = frames
        self.out_features = joints * width
        self.embed = nn.Linear(in_channels + extra_per_joint, width)
        self.joint_position = nn.Parameter(torch.randn(1, joints, width) * 0.02)
        self.spatial = _transformer(width, layers, width // SPATIAL_HEAD_FEATURES)
        self.frame_position = nn.Parameter(torch.randn(1, frames, self.out_features) * 0.02)
        self.temporal = _transformer(self.out_features, layers, TEMPORAL_HEADS)
        self.norm = nn.LayerNorm(self.out_features)
        self.frame_weights = nn.Linear(frames, 1)

    def forward(self, x: torch.Tensor, extra: torch.Tensor | None = None) -> torch.Tensor:
        batch, frames, joints, _ = x.shape
        if frames != self.receptive_field:
            raise ValueError(f"PoseTransformer: expected {self.receptive_field} frames, got {frames}")
        if extra is not None:
            x = torch.cat([x, extra[..., None]], dim=-1)
        tokens = self.embed(x).reshape(batch * frames, joints, -1) + self.joint_position
        per_frame = self.spatial(tokens).reshape(batch, frames, self.out_features) + self.frame_position
        encoded = self.norm(self.temporal(per_frame))
        return self.frame_weights(encoded.transpose(1, 2))[..., 0]
