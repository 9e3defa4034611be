"""``LiftingNetwork``: Ray3D, its ablations and the paper's learned baselines as one configurable module.

A network has a pose branch (root-relative joints) and a trajectory branch (the root), each with its own
backbone, and predicts in its ``output_frame`` (the NCS for Ray3D, the camera frame for the baselines).
What differs between the methods is only configuration (see ``presets.py``):

- input: ``ncs_rays`` (Ray3D), ``camera_rays`` (intrinsic decoupling only), ``pixels`` (normalised by the
  image width, VideoPose3D-style) or ``pixels_centred`` (principal point removed, PoseLifter-style);
- backbone: ``rie`` (grouped, RIE), ``tcn`` (one temporal conv stack, VideoPose3D), ``mlp`` (single frame) or
  ``transformer`` (spatial then temporal attention, PoseFormer);
- camera embedding of (height, pitch) concatenated to every decoder input, or not;
- root: ``xyz`` (regressed directly, the paper), ``ray_depth`` (the depth along the root's observed ray,
  regressed in log space: the root's direction is known from its pixel, only its distance is not) or
  ``focal_depth`` (PoseLifter: a canonical depth times the focal length);
- ground features: the inverse depth at which each joint's ray meets the floor, ``ray_y / h`` in the NCS,
  given to the encoders (the ground-plane cue that camera height and pitch make available).
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import torch
from torch import nn

from ray3d.geometry import CameraBatch
from ray3d.geometry import transforms as tf
from ray3d.models.blocks import CameraEmbedding, receptive_field
from ray3d.models.branches import BRANCHES
from ray3d.models.tensor_batch import TensorBatch
from ray3d.skeleton import LAYOUTS, Skeleton, flip, layout_skeleton
from ray3d.temporal import Window

INPUTS = ("ncs_rays", "camera_rays", "pixels", "pixels_centred")
BACKBONES = tuple(BRANCHES)
ROOTS = ("xyz", "ray_depth", "focal_depth")
DEPTH_SCALE_M = 5.0      # log-depth outputs are relative to this
CANONICAL_FOCAL_PX = 1000.0


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    name: str = "ray3d"
    layout: str = "h36m17"              # the input joints
    output_layout: str | None = None    # the predicted joints; None: the input's
    confidence_input: bool = False      # each joint's detector confidence as one more input channel
    input: str = "ncs_rays"
    backbone: str = "rie"
    camera_embedding: bool = True
    output_frame: str = "ncs"
    root: str = "ray_depth"
    ground_features: bool = True
    kernels: tuple[int, ...] = (3, 3)   # temporal conv widths; the window is their product (one: a transformer's)
    root_kernels: tuple[int, ...] | None = None  # the trajectory branch's own, longer context; None: ``kernels``
    channels: int = 128                 # conv channels; for the transformer, each joint's feature size
    layers: int = 2                     # transformer blocks, spatial and temporal each
    hidden: int = 256
    dropout: float = 0.1
    fusion: bool = False
    remove_roll: bool = False  # gravity-aligned NCS: undo the camera roll too (the paper keeps it)
    causal: bool = False       # predict the window's last frame from it and the frames before (live use)

    def __post_init__(self) -> None:
        object.__setattr__(self, "kernels", tuple(self.kernels))
        if self.root_kernels is not None:
            object.__setattr__(self, "root_kernels", tuple(self.root_kernels))
        checks = [
            (self.input in INPUTS, f"input must be one of {INPUTS}"),
            (self.backbone in BACKBONES, f"backbone must be one of {BACKBONES}"),
            (self.root in ROOTS, f"root must be one of {ROOTS}"),
            (self.output_frame in ("ncs", "camera"), "output_frame must be 'ncs' or 'camera'"),
            (self.output_frame == "camera" or self.input == "ncs_rays", "an NCS output needs ncs_rays input"),
            (not self.ground_features or self.input == "ncs_rays", "ground features need ncs_rays input"),
            (self.root != "ray_depth" or self.input.endswith("rays"), "ray_depth needs ray input"),
            (self.root != "focal_depth" or self.output_frame == "camera", "focal_depth predicts in the camera frame"),
            (self.backbone != "mlp" or self.frames == 1, "the mlp backbone sees a single frame: kernels (1,)"),
            (self.backbone != "transformer" or len(self.kernels) == 1,
             "the transformer backbone's window is one number: kernels (F,)"),
            (self.backbone != "transformer" or self.layers >= 1, "the transformer backbone needs layers >= 1"),
            (self.layout in LAYOUTS, f"layout must be one of {tuple(LAYOUTS)}"),
            (self.output_layout is None or self.output_layout in LAYOUTS,
             f"output_layout must be one of {tuple(LAYOUTS)}"),
            (self._groups_decodable(), "output_layout: every joint group it has must be in the input layout too"),
            (self.root_kernels is None or self.backbone in ("rie", "tcn"),
             "root_kernels: only the temporal-convolution backbones (rie, tcn) have kernels per branch"),
            (self.root_kernels is None or receptive_field(self.root_kernels) % 2 == 1,
             "root_kernels: the trajectory window must have an odd number of frames, as the pose window"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(f"ModelConfig {self.name}: {message}")

    def _groups_decodable(self) -> bool:
        if self.layout not in LAYOUTS or self.output_layout not in (None, *LAYOUTS):
            return True  # reported by the layout checks
        inputs, outputs = self.input_skeleton.groups, self.output_skeleton.groups
        return all(inputs[g] for g, joints in outputs.items() if joints)

    @property
    def input_skeleton(self) -> Skeleton:
        return layout_skeleton(self.layout)

    @property
    def output_skeleton(self) -> Skeleton:
        return layout_skeleton(self.output_layout or self.layout)

    @property
    def frames(self) -> int:
        """The window: the longer of the two branches' receptive fields."""
        return max(receptive_field(self.kernels), receptive_field(self.branch_kernels("root")))

    def branch_kernels(self, outputs: str) -> tuple[int, ...]:
        """The temporal kernels of the pose branch (``"pose"``) or the trajectory branch (``"root"``)."""
        return self.root_kernels if outputs == "root" and self.root_kernels is not None else self.kernels

    @property
    def window(self) -> Window:
        """The temporal window: the receptive field, and which of its frames is predicted."""
        return Window(self.frames, self.causal)

    @property
    def input_channels(self) -> int:
        return (3 if self.input.endswith("rays") else 2) + int(self.confidence_input)


class Predictor(Protocol):
    """What lifting and evaluation need of a network: a ``LiftingNetwork``, its inference form, or an inference
    backend (``models.backends``)."""

    config: ModelConfig
    receptive_field: int

    def predict(self, batch: TensorBatch, flip_test: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """(pose (B, J, 3) root-relative, root (B, 3)) in the model's output frame."""

    def to_world(self, points: torch.Tensor, cameras: CameraBatch, camera_params: torch.Tensor) -> torch.Tensor:
        """(B, ..., 3) points in the model's output frame -> world."""


class LiftingNetwork(nn.Module):
    """Pose and trajectory branches; ``forward`` returns (pose (B, J, 3) root-relative, root (B, 3)) in the
    configured output frame."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        self.skeleton, self.output_skeleton = config.input_skeleton, config.output_skeleton
        self.receptive_field = config.frames
        root_outputs = 3 if config.root == "xyz" else 1
        self.pose_net = BRANCHES[config.backbone](config, "pose", root_outputs)
        self.trajectory_net = BRANCHES[config.backbone](config, "root", root_outputs)
        self.pose_camera = CameraEmbedding(config.dropout) if config.camera_embedding else None
        self.trajectory_camera = CameraEmbedding(config.dropout) if config.camera_embedding else None

    def network_input(self, batch: TensorBatch) -> torch.Tensor:
        """(B, F, J, C): the geometric input of each joint, then its confidence when the model reads it."""
        geometric = self._geometric_input(batch)
        if not self.config.confidence_input:
            return geometric
        return torch.cat([geometric, batch.confidences[..., None].to(geometric.dtype)], dim=-1)

    def _geometric_input(self, batch: TensorBatch) -> torch.Tensor:
        kind = self.config.input
        if kind == "ncs_rays":
            return batch.rays
        if kind == "camera_rays":
            return tf.rays_normalized_to_camera(batch.rays, batch.camera_params[:, 1, None, None],
                                                self._roll(batch, (None, None)))
        width = batch.image_width
        if kind == "pixels":
            return torch.stack([batch.pixels[..., 0] / width * 2 - 1, batch.pixels[..., 1] / width * 2], -1)
        principal = batch.intrinsics[:, None, None, 2:]
        return (batch.pixels - principal) / width * 2

    def forward(self, batch: TensorBatch) -> tuple[torch.Tensor, torch.Tensor]:
        x = self.network_input(batch)
        if x.shape[1] != self.receptive_field:
            raise ValueError(f"{self.config.name}: expected windows of {self.receptive_field} frames, got {x.shape[1]}")
        extra = batch.rays[..., 1] / batch.camera_params[:, None, None, 0] if self.config.ground_features else None
        cameras = [None, None] if self.pose_camera is None else [
            self.pose_camera(batch.camera_params), self.trajectory_camera(batch.camera_params)]
        pose = self.pose_net(x, extra, cameras[0])
        pose = pose - pose[:, :1]  # root-relative: the root row is exactly zero
        return pose, self._root(self.trajectory_net(x, extra, cameras[1]), batch)

    def _root(self, out: torch.Tensor, batch: TensorBatch) -> torch.Tensor:
        if self.config.root == "xyz":
            return out
        depth = torch.exp(out[:, 0]) * DEPTH_SCALE_M
        target = self.config.window.target
        if self.config.root == "focal_depth":
            depth = depth * batch.intrinsics[:, 0] / CANONICAL_FOCAL_PX
            pixel = batch.pixels[:, target, 0]
            xy = (pixel - batch.intrinsics[:, 2:]) / batch.intrinsics[:, :2]
            return torch.cat([xy * depth[:, None], depth[:, None]], dim=-1)
        ray = batch.rays[:, target, 0]
        if self.config.output_frame == "camera":
            return depth[:, None] * tf.rays_normalized_to_camera(ray, batch.camera_params[:, 1], self._roll(batch))
        origin = torch.stack([torch.zeros_like(depth), -batch.camera_params[:, 0], torch.zeros_like(depth)], -1)
        return depth[:, None] * ray + origin

    def to_world(self, points: torch.Tensor, cameras: CameraBatch, camera_params: torch.Tensor) -> torch.Tensor:
        """(B, ..., 3) points in this model's output frame -> world, with the batch's cameras."""
        return frame_to_world(points, self.config.output_frame, cameras, camera_params, self.config.remove_roll)

    def targets(self, batch: TensorBatch, pose_ncs: torch.Tensor, root_ncs: torch.Tensor):
        """The sample generator's NCS targets in this model's output frame."""
        return targets_in_frame(batch, pose_ncs, root_ncs, self.config.output_frame, self.config.remove_roll)

    def _roll(self, batch: TensorBatch, extra_axes: tuple = ()) -> torch.Tensor | None:
        return batch.roll[(slice(None), *extra_axes)] if self.config.remove_roll else None

    def predict(self, batch: TensorBatch, flip_test: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """``forward``, optionally averaged with the mirrored input's mirrored prediction."""
        return predict_with_flip(self, self.config, batch, flip_test)


def predict_with_flip(forward, config: ModelConfig, batch: TensorBatch, flip_test: bool):
    """(pose, root) from ``forward(batch)``, averaged with the mirrored input's mirrored output when asked."""
    pose, root = forward(batch)
    if flip_test:
        flipped_pose, flipped_root = forward(batch.flipped(config.input_skeleton))
        pose = (pose + flip(flipped_pose, config.output_skeleton)) / 2
        root = (root + flipped_root * root.new_tensor([-1.0, 1.0, 1.0])) / 2
    return pose, root


def predict_world(model: Predictor, batch: TensorBatch, cameras: CameraBatch, flip_test: bool = False) -> torch.Tensor:
    """(B, J, 3) world joints (float64) of the windows' target frames: ``model.predict`` (a ``LiftingNetwork``
    or an inference backend), then the model's output frame back to the world. The one way from network output
    to the world, for lifting, evaluation and validation alike."""
    pose, root = model.predict(batch, flip_test)
    return model.to_world(pose.double() + root.double()[:, None], cameras, batch.camera_params.double())


def frame_to_world(points: torch.Tensor, frame: str, cameras: CameraBatch, camera_params: torch.Tensor,
                   remove_roll: bool = False) -> torch.Tensor:
    """(B, ..., 3) points in a model's output frame -> world, with the batch's cameras."""
    def per_sample(array) -> torch.Tensor:
        tensor = torch.as_tensor(array, dtype=points.dtype, device=points.device)
        return tensor[(slice(None), *(None,) * (points.ndim - 2))]

    if frame == "ncs":
        points = tf.normalized_to_camera(points, per_sample(camera_params[:, 0]), per_sample(camera_params[:, 1]),
                                         per_sample(cameras.roll) if remove_roll else None)
    return tf.camera_to_world(points, per_sample(cameras.R), per_sample(cameras.t))


def targets_in_frame(batch: TensorBatch, pose_ncs: torch.Tensor, root_ncs: torch.Tensor, frame: str,
                     remove_roll: bool = False):
    """The NCS targets of a batch expressed in ``frame`` (undoing the pitch, and roll if removed)."""
    if frame == "ncs":
        return pose_ncs, root_ncs
    roll = batch.roll if remove_roll else None
    root = tf.normalized_to_camera(root_ncs, batch.camera_params[:, 0], batch.camera_params[:, 1], roll)
    pose = tf.rays_normalized_to_camera(pose_ncs, batch.camera_params[:, 1, None],
                                        None if roll is None else roll[:, None])
    return pose, root


def lifting_loss(pose: torch.Tensor, root: torch.Tensor, target_pose: torch.Tensor, target_root: torch.Tensor):
    """The brief's loss: MPJPE of the root-relative pose + the root error weighted per sample by 1 / |z|."""
    pose_error = (pose - target_pose).norm(dim=-1).mean()
    root_error = ((root - target_root).norm(dim=-1) / target_root[:, 2].abs().clamp(min=0.5)).mean()
    return pose_error + root_error, pose_error.detach(), root_error.detach()


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def flops_per_frame(model: LiftingNetwork) -> float:
    """Floating-point operations (multiply-adds x 2) for one output frame, counted by torch."""
    from torch.utils.flop_counter import FlopCounterMode

    batch = TensorBatch.example(model.receptive_field, model.skeleton.num_joints, 2)
    was_training = model.training
    model.eval()
    # With gradients on: without them the transformer layers take a fused kernel the counter does not see.
    with FlopCounterMode(display=False) as counter:
        model(batch)
    model.train(was_training)
    return counter.get_total_flops() / 2


