"""The inference form of a ``LiftingNetwork``: the same function, laid out for speed once training is over.

Two changes, both exact up to float rounding (tests: every preset, within 1e-5 m):

- every batch norm is folded into the linear layer before it (inference uses its running statistics, so it is
  an affine map per channel), and inference-time dropout is dropped;
- the RIE branches' five per-group encoders, fusion layers and decoders run as one batched product per layer
  (``torch.baddbmm`` over stacked, zero-padded group weights) instead of five small ones.

Why not train in this form: at a training batch the five products are no slower than one batched product on 2
cores (the batch splits 3:2 over the threads), and stacked batch norms need a transposed copy per layer; at batch
1 the Python and dispatch cost of about 300 small operators is the whole latency (docs/RESULTS.md, issue 15).
"""

from __future__ import annotations

import copy

import torch
import torch.nn.functional as F
from torch import nn

from ray3d.models.blocks import BatchNorm, Dropout, TemporalEncoder
from ray3d.models.branches import RIEBranch, branch_window
from ray3d.models.network import LiftingNetwork
from ray3d.models.rie import RIEBackbone, rie_encodings, rie_global_input
from ray3d.temporal import target_frame

_SLOPE = 0.2  # the LeakyReLU of every unit (blocks._conv_unit, blocks.mlp)
# From this many windows the branch's own per-group layers (batch norms folded) are faster than the stacked ones:
# one batched product splits its five groups 3:2 over 2 threads, and the padding of the smaller groups costs
# (lite, dev-cpu-3: stacked 339 / 5,533 / 10,429 frames/s at batch 1 / 32 / 128, per group 149 / 3,560 / 11,081).
BATCH_PER_GROUP = 128


def inference_network(model: LiftingNetwork) -> LiftingNetwork:
    """A copy of ``model`` in its inference form (eval mode; it cannot be trained); ``model`` itself when it is
    one already."""
    if getattr(model, "inference_form", False):
        return model
    fused = copy.deepcopy(model).eval()
    for name in ("pose_net", "trajectory_net"):
        branch = getattr(fused, name)
        if isinstance(branch, RIEBranch):
            setattr(fused, name, StackedRIEBranch(branch))
    fold_batch_norms(fused)
    fused.inference_form = True
    return fused.to(next(model.parameters()).device)  # the index buffers were made on the CPU


def _folded(weight: torch.Tensor, bias: torch.Tensor | None, norm: nn.BatchNorm1d) -> tuple[torch.Tensor, torch.Tensor]:
    """(out, in) weight and (out,) bias of ``norm(linear(x))`` as one linear map."""
    scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)
    shift = norm.bias - norm.running_mean * scale
    return weight * scale[:, None], shift if bias is None else shift + bias * scale


@torch.no_grad()
def fold_batch_norms(module: nn.Module) -> None:
    """In place: each ``Linear`` followed by a ``BatchNorm`` in an ``nn.Sequential`` becomes one ``Linear`` with a
    bias, and the norm and the inference-time dropouts leave the sequence (each module call costs ~10 us)."""
    for sequential in [m for m in module.modules() if isinstance(m, nn.Sequential)]:
        layers = list(sequential)
        for layer, following in zip(layers, layers[1:]):
            if isinstance(layer, nn.Linear) and isinstance(following, BatchNorm):
                weight, bias = _folded(layer.weight, layer.bias, following)
                layer.weight = nn.Parameter(weight, requires_grad=False)
                layer.bias = nn.Parameter(bias, requires_grad=False)
        kept = [layer for layer in layers if not isinstance(layer, (BatchNorm, Dropout, nn.Dropout))]
        for name in list(sequential._modules):
            del sequential._modules[name]
        for i, layer in enumerate(kept):
            sequential.add_module(str(i), layer)


class InferenceOnly(nn.Module):
    """A module that only infers: ``train()`` is refused with ``cannot_train``, ``eval()`` kept."""

    cannot_train = "this network cannot be trained"

    def train(self, mode: bool = True):
        if mode:
            raise ValueError(self.cannot_train)
        return super().train(False)


class StackedLinear(nn.Module):
    """G linear maps at once: (G, N, in) -> (G, N, out), ``bias + x @ weight`` per group."""

    def __init__(self, weights: list[torch.Tensor], biases: list[torch.Tensor],
                 in_columns: list[torch.Tensor] | None = None, out_rows: list[torch.Tensor] | None = None,
                 in_features: int | None = None, out_features: int | None = None):
        """``weights[g]`` (out_g, in_g) and ``biases[g]`` (out_g,) of group g; groups of different widths are
        zero-padded: group g's inputs are columns ``in_columns[g]`` of the ``in_features``, its outputs rows
        ``out_rows[g]`` of the ``out_features``."""
        super().__init__()
        groups = len(weights)
        in_features = in_features or weights[0].shape[1]
        out_features = out_features or weights[0].shape[0]
        weight = weights[0].new_zeros(groups, in_features, out_features)
        bias = weights[0].new_zeros(groups, 1, out_features)
        for g, (w, b) in enumerate(zip(weights, biases)):
            rows = slice(None) if out_rows is None else out_rows[g]
            block = w.new_zeros(in_features, w.shape[0])
            block[slice(None) if in_columns is None else in_columns[g]] = w.T
            weight[g][:, rows] = block
            bias[g, 0, rows] = b
        self.register_buffer("weight", weight)
        self.register_buffer("bias", bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.bias, x, self.weight)


def _folded_unit(sequential: nn.Sequential) -> tuple[torch.Tensor, torch.Tensor]:
    """(out, in) weight and (out,) bias of a Linear-BatchNorm pair, the norm folded in."""
    return _folded(sequential[0].weight, sequential[0].bias, sequential[1])


def _padded_columns(kernel: int, width: int, padded_width: int, joints_width: int, padded_joints_width: int):
    """Where a group's input columns (``kernel`` frames of ``width``: its joints' ``joints_width`` features,
    then the extra ones) lie among the ``kernel`` frames of ``padded_width`` of the padded layout."""
    frame = torch.cat([torch.arange(joints_width), padded_joints_width + torch.arange(width - joints_width)])
    return torch.cat([f * padded_width + frame for f in range(kernel)])


class StackedRIEBranch(InferenceOnly):
    """An ``RIEBranch`` in inference form: its groups' layers stacked, batch norms folded."""

    cannot_train = "the inference form of a network (batch norms folded) cannot be trained"

    def __init__(self, branch: RIEBranch):
        super().__init__()
        backbone: RIEBackbone = branch.backbone
        self.outputs, self.frames = branch.outputs, branch.frames
        self.causal, self.num_joints = backbone.causal, backbone.skeleton.num_joints
        groups = list(backbone.groups.values())
        encoders: list[TemporalEncoder] = list(backbone.encoders.values())
        self.kernels = encoders[0].kernels
        self.padded_joints = max(len(j) for j in groups)
        # A group's joints, padded with the index of an all-zero joint appended to the input.
        self.register_buffer("joint_index", torch.tensor(
            [j + [self.num_joints] * (self.padded_joints - len(j)) for j in groups]))
        per_joint = 3 * branch.config.input_channels  # input, positional and temporal encodings
        extra = encoders[0].expand[0].in_features // self.kernels[0] - per_joint * len(groups[0])
        width = per_joint * self.padded_joints + extra
        k0 = self.kernels[0]
        columns = [_padded_columns(k0, per_joint * len(j) + extra, width, per_joint * len(j),
                                   per_joint * self.padded_joints) for j in groups]
        self.expand = StackedLinear(*zip(*(_folded_unit(e.expand) for e in encoders)), in_columns=columns,
                                    in_features=k0 * width)
        self.blocks = nn.ModuleList(
            nn.ModuleList(StackedLinear(*zip(*(_folded_unit(e.blocks[b][u]) for e in encoders))) for u in range(2))
            for b in range(len(self.kernels) - 1))
        self.per_group = branch  # folded by ``inference_network``, as the modules shared with it below
        self.batch_per_group = BATCH_PER_GROUP
        self.global_branch = backbone.global_branch
        self.fusion = None if backbone.fusion is None else StackedLinear(
            [f[0].weight for f in backbone.fusion.values()], [f[0].bias for f in backbone.fusion.values()])
        count = len(groups)
        self.register_buffer("others", torch.tensor([[o for o in range(count) if o != g] for g in range(count)]))
        if self.outputs == "pose":
            decoders = list(branch.decoders.values())
            outputs = [branch.output_groups[g] for g in backbone.groups]
            self.padded_outputs = max(len(j) for j in outputs)
            self.decode_hidden = StackedLinear(*zip(*(_folded_unit(d) for d in decoders)))
            rows = [torch.arange(3 * len(j)) for j in outputs]
            self.decode_out = StackedLinear([d[-1].weight for d in decoders], [d[-1].bias for d in decoders],
                                            out_rows=rows, out_features=3 * self.padded_outputs)
            slots = torch.empty(branch.output_skeleton.num_joints, dtype=torch.long)
            for g, joints in enumerate(outputs):
                slots[torch.tensor(joints, dtype=torch.long)] = g * self.padded_outputs + torch.arange(len(joints))
            self.register_buffer("slots", slots)
        else:
            self.head = branch.head


    def forward(self, x: torch.Tensor, extra: torch.Tensor | None, camera: torch.Tensor | None) -> torch.Tensor:
        if x.shape[0] >= self.batch_per_group:
            return self.per_group(x, extra, camera)
        x, extra = branch_window(x, extra, self.frames, self.causal)
        batch, frames = x.shape[:2]
        groups = self.joint_index.shape[0]
        encoded = F.pad(rie_encodings(x, self.causal), (0, 0, 0, 1))  # the zero joint padding groups
        h = encoded[:, :, self.joint_index].permute(2, 0, 1, 3, 4).reshape(groups, batch, frames, -1)
        if extra is not None:
            h = torch.cat([h, extra.expand(groups, -1, -1, -1)], dim=-1)
        h = self._unit(self.expand, h, self.kernels[0])
        for k, (wide, narrow) in zip(self.kernels[1:], self.blocks):
            h = h[:, :, target_frame(k, self.causal)::k] + self._unit(narrow, self._unit(wide, h, k), 1)
        features = h[:, :, 0]  # (G, B, C)
        global_feature = self.global_branch(rie_global_input(x, extra, self.causal))
        if self.fusion is not None:
            others = features[self.others].permute(0, 2, 1, 3).reshape(groups, batch, -1)
            features = features + F.leaky_relu(self.fusion(others), _SLOPE)
        tail = [] if camera is None else [camera]
        if self.outputs == "pose":
            shared = torch.cat([global_feature, *tail], dim=-1).expand(groups, -1, -1)
            hidden = F.leaky_relu(self.decode_hidden(torch.cat([features, shared], dim=-1)), _SLOPE)
            decoded = self.decode_out(hidden).view(groups, batch, self.padded_outputs, 3)
            return decoded.transpose(0, 1).reshape(batch, -1, 3)[:, self.slots]
        return self.head(torch.cat([features.transpose(0, 1).reshape(batch, -1), global_feature, *tail], dim=-1))

    @staticmethod
    def _unit(layer: StackedLinear, h: torch.Tensor, kernel: int) -> torch.Tensor:
        """A stride-``kernel`` temporal unit on (G, B, L, C): (G, B, L / kernel, out)."""
        groups, batch, length, channels = h.shape
        out = layer(h.reshape(groups, batch * (length // kernel), kernel * channels))
        return F.leaky_relu_(out, _SLOPE).view(groups, batch, length // kernel, -1)
