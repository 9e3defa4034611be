"""A network's two branches (the pose and the trajectory), one small class per backbone, chosen from
``BRANCHES`` by ``ModelConfig.backbone``: adding a backbone is adding a class here and a row in the table.

Every branch maps the model's window, ``x`` (B, F, J, C) with ``extra`` (B, F, E) per-frame features and the
optional camera embedding (B, K), to the pose (B, J_out, 3) or the root's outputs (B, k). A branch whose own
window is shorter than the model's sees the frames around the target (the last ones when causal).
"""

from __future__ import annotations

import torch
from torch import nn

from ray3d.models.blocks import CameraEmbedding, TemporalEncoder, mlp, receptive_field
from ray3d.models.poseformer import PoseTransformer
from ray3d.models.rie import RIEBackbone
from ray3d.temporal import Window


def branch_window(x: torch.Tensor, extra: torch.Tensor | None, frames: int, causal: bool):
    """A branch's own window of the model's: the ``frames`` around the target frame (the last ones when causal)
    of ``x`` (B, F, ...) and ``extra`` (B, F, E), when that branch sees fewer frames than the model."""
    if x.shape[1] == frames:
        return x, extra
    window = Window(x.shape[1], causal).around_target(frames)
    return x[:, window], None if extra is None else extra[:, window]


class Branch(nn.Module):
    """What every branch shares: its config, which outputs it predicts (``"pose"`` or ``"root"``), its window
    and the widths its head takes. Subclasses build ``backbone`` and their head(s) and define ``predict``."""

    def __init__(self, config, outputs: str, root_outputs: int):
        super().__init__()
        self.config, self.outputs = config, outputs
        self.input_skeleton, self.output_skeleton = config.input_skeleton, config.output_skeleton
        self.kernels = config.branch_kernels(outputs)
        self.frames = receptive_field(self.kernels)
        self.camera_features = CameraEmbedding.out_features if config.camera_embedding else 0
        self.extra_features = self.input_skeleton.num_joints if config.ground_features else 0
        self.out_features = 3 * self.output_skeleton.num_joints if outputs == "pose" else root_outputs

    def forward(self, x: torch.Tensor, extra: torch.Tensor | None, camera: torch.Tensor | None) -> torch.Tensor:
        x, extra = branch_window(x, extra, self.frames, self.config.causal)
        out = self.predict(x, extra, [camera] if camera is not None else [])
        return out.view(x.shape[0], self.output_skeleton.num_joints, 3) if self.outputs == "pose" else out

    def predict(self, x: torch.Tensor, extra: torch.Tensor | None, tail: list[torch.Tensor]) -> torch.Tensor:
        raise NotImplementedError


class RIEBranch(Branch):
    """RIE (grouped): each joint group's features decode that group's joints of the output layout; the root
    reads every group's features and the global one."""

    def __init__(self, config, outputs: str, root_outputs: int):
        super().__init__(config, outputs, root_outputs)
        c, h = config.channels, config.hidden
        self.backbone = RIEBackbone(self.input_skeleton, config.input_channels, c, h, self.kernels, config.dropout,
                                    config.fusion, self.extra_features, config.causal)
        groups = self.backbone.groups
        if outputs == "pose":
            self.output_groups = {g: list(self.output_skeleton.groups[g]) for g in groups}
            for g, joints in self.output_groups.items():
                self.register_buffer(f"_outputs_{g}", torch.tensor(joints, dtype=torch.long), persistent=False)
            self.decoders = nn.ModuleDict({g: mlp(2 * c + self.camera_features, h, 3 * len(j), 1, config.dropout)
                                           for g, j in self.output_groups.items()})
        else:
            self.head = mlp(c * (len(groups) + 1) + self.camera_features, h, root_outputs, 1, config.dropout)

    def predict(self, x, extra, tail):
        features, global_feature = self.backbone(x, extra)
        if self.outputs == "root":
            return self.head(torch.cat([*features.values(), global_feature, *tail], dim=-1))
        pose = x.new_zeros(x.shape[0], self.output_skeleton.num_joints, 3)
        for g, joints in self.output_groups.items():
            decoded = self.decoders[g](torch.cat([features[g], global_feature, *tail], dim=-1))
            pose = pose.index_copy(1, self.output_index(g), decoded.view(x.shape[0], len(joints), 3))
        return pose

    def output_index(self, group: str) -> torch.Tensor:
        """The output joints ``group`` decodes, as an index tensor (on the module's device)."""
        return getattr(self, f"_outputs_{group}")


class TransformerBranch(Branch):
    """PoseFormer-style attention, then PoseFormer's head: a LayerNorm and a Linear (a batch norm after the
    attention layers learns features so narrow that its running statistics no longer fit any one batch)."""

    def __init__(self, config, outputs: str, root_outputs: int):
        super().__init__(config, outputs, root_outputs)
        self.backbone = PoseTransformer(self.input_skeleton.num_joints, config.input_channels, config.channels,
                                        config.layers, self.frames, int(config.ground_features))
        width = self.backbone.out_features + self.camera_features
        self.head = nn.Sequential(nn.LayerNorm(width), nn.Linear(width, self.out_features))

    def predict(self, x, extra, tail):
        return self.head(torch.cat([self.backbone(x, extra), *tail], dim=-1))


class TCNBranch(Branch):
    """VideoPose3D: one temporal convolution stack over every joint's inputs at once, then an MLP head."""

    def __init__(self, config, outputs: str, root_outputs: int):
        super().__init__(config, outputs, root_outputs)
        self.backbone = self.encoder(config.input_channels * self.input_skeleton.num_joints + self.extra_features)
        self.head = mlp(config.channels + self.camera_features, config.hidden, self.out_features, 1, config.dropout)

    def encoder(self, features: int) -> nn.Module:
        return TemporalEncoder(features, self.config.channels, self.kernels, self.config.dropout, self.config.causal)

    def encode(self, flat: torch.Tensor) -> torch.Tensor:
        """(B, F, features) -> (B, channels)."""
        return self.backbone(flat)

    def predict(self, x, extra, tail):
        flat = x.reshape(x.shape[0], x.shape[1], -1)
        if extra is not None:
            flat = torch.cat([flat, extra], dim=-1)
        return self.head(torch.cat([self.encode(flat), *tail], dim=-1))


class MLPBranch(TCNBranch):
    """A single frame through an MLP (the paper's one-frame baseline): the TCN branch with a per-frame encoder."""

    def encoder(self, features: int) -> nn.Module:
        return mlp(features, self.config.hidden, self.config.channels, 2, self.config.dropout)

    def encode(self, flat: torch.Tensor) -> torch.Tensor:
        return self.backbone(flat[:, 0])


BRANCHES: dict[str, type[Branch]] = {"rie": RIEBranch, "tcn": TCNBranch, "mlp": MLPBranch,
                                     "transformer": TransformerBranch}
