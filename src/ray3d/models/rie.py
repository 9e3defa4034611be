"""The RIE backbone (Shan et al. 2021), written from the description in the brief: per joint group a temporal
encoder over the group's inputs plus positional (joint minus root) and temporal (frame minus centre frame)
encodings; a global branch over the centre frame of all joints; optional feature fusion between groups. A causal
backbone uses the window's last frame where the centred one uses its centre."""

from __future__ import annotations

import torch
from torch import nn

from ray3d.models.blocks import TemporalEncoder, mlp
from ray3d.skeleton import GROUP_NAMES, Skeleton
from ray3d.temporal import target_frame


def rie_encodings(x: torch.Tensor, causal: bool = False) -> torch.Tensor:
    """(B, F, J, C) -> (B, F, J, 3C): the input with its positional (minus the root) and temporal (minus the
    target frame) encodings."""
    target = target_frame(x.shape[1], causal)
    positional = x - x[:, :, :1]
    temporal = x - x[:, target:target + 1]
    return torch.cat([x, positional, temporal], dim=-1)


def rie_global_input(x: torch.Tensor, extra: torch.Tensor | None, causal: bool = False) -> torch.Tensor:
    """(B, F, J, C) inputs and optional (B, F, E) extra features -> (B, J * C + E): the target frame's, which
    the global branch sees."""
    target = target_frame(x.shape[1], causal)
    global_input = x[:, target].reshape(x.shape[0], -1)
    return global_input if extra is None else torch.cat([global_input, extra[:, target]], dim=-1)


class RIEBackbone(nn.Module):
    """(B, F, J, C) per-joint inputs -> per-group features {group: (B, channels)} and a global feature.

    Groups come from the skeleton's joint names (``Skeleton.groups``), so 17-, 14- and 15-joint layouts work.
    The target frame is ``F // 2``, the true middle of the (odd) receptive field, or ``F - 1`` when ``causal``.
    """

    def __init__(self, skeleton: Skeleton, in_channels: int, channels: int, hidden: int, kernels: tuple[int, ...],
                 dropout: float, fusion: bool, extra_features: int = 0, causal: bool = False):
        super().__init__()
        self.skeleton, self.causal = skeleton, causal
        self.groups = {g: list(skeleton.groups[g]) for g in GROUP_NAMES if skeleton.groups[g]}
        # Index tensors for index_select, much faster than indexing with Python lists; not saved in checkpoints.
        for g, joints in self.groups.items():
            self.register_buffer(f"_joints_{g}", torch.tensor(joints), persistent=False)
        per_joint = 3 * in_channels  # input, positional encoding, temporal encoding
        self.encoders = nn.ModuleDict({
            g: TemporalEncoder(per_joint * len(joints) + extra_features, channels, kernels, dropout, causal)
            for g, joints in self.groups.items()})
        self.receptive_field = next(iter(self.encoders.values())).receptive_field
        self.global_branch = mlp(in_channels * skeleton.num_joints + extra_features, hidden, channels, 1, dropout)
        self.fusion = nn.ModuleDict({
            g: nn.Sequential(nn.Linear(channels * (len(self.groups) - 1), channels), nn.LeakyReLU(0.2))
            for g in self.groups}) if fusion else None
        self.channels = channels

    def group_index(self, group: str) -> torch.Tensor:
        """The joints of ``group`` as an index tensor (on the module's device)."""
        return getattr(self, f"_joints_{group}")

    def forward(self, x: torch.Tensor,
                extra: torch.Tensor | None = None) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
        """``extra``: optional (B, F, E) per-frame features given to every group and the global branch."""
        batch, frames = x.shape[:2]
        encoded = rie_encodings(x, self.causal)
        features = {}
        for g in self.groups:
            group_input = encoded.index_select(2, self.group_index(g)).reshape(batch, frames, -1)
            if extra is not None:
                group_input = torch.cat([group_input, extra], dim=-1)
            features[g] = self.encoders[g](group_input)
        global_feature = self.global_branch(rie_global_input(x, extra, self.causal))
        if self.fusion is not None:
            features = {g: f + self.fusion[g](torch.cat([features[o] for o in self.groups if o != g], dim=-1))
                        for g, f in features.items()}
        return features, global_feature
