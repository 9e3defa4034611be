"""The inference form (``models.inference``): the same function as the network as trained, within float rounding,
on both of its paths (stacked groups for small batches, per-group layers for large ones), for every preset."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ray3d import cameras
from ray3d.checkpoints import load_model
from ray3d.demo import demo_clip
from ray3d.lifting.lifter import Lifter
from ray3d.models import PRESETS, LiftingNetwork, TensorBatch, preset
from ray3d.models.backends import TorchScriptLiftingModel
from ray3d.models.blocks import BatchNorm, Dropout
from ray3d.models.inference import BATCH_PER_GROUP, StackedRIEBranch, inference_network

CONFIGS = {**PRESETS,
           "root27": preset("ray3d", name="root27", root_kernels=(3, 3, 3)),
           "humaneva15": preset("ray3d", name="humaneva15", layout="humaneva15"),
           "detector18": preset("ray3d", name="detector18", layout="detector18", output_layout="h36m17",
                                confidence_input=True),
           "paper-small": preset("ray3d-paper", name="paper-small", channels=16, hidden=32)}
CONFIGS.pop("ray3d-paper")  # its 46 M parameters: the small copy has the same structure (fusion)


def _trained_looking(config) -> LiftingNetwork:
    """A randomly initialised network whose batch norms hold running statistics far from (0, 1), as after
    training: folding them must matter."""
    model = LiftingNetwork(config).eval()
    generator = torch.Generator().manual_seed(3)
    with torch.no_grad():
        for module in model.modules():
            if isinstance(module, BatchNorm):
                n = module.num_features
                module.running_mean.copy_(torch.randn(n, generator=generator) * 0.5)
                module.running_var.copy_(torch.rand(n, generator=generator) * 2 + 0.2)
                module.weight.copy_(torch.rand(n, generator=generator) + 0.5)
                module.bias.copy_(torch.randn(n, generator=generator) * 0.2)
    return model


@pytest.mark.parametrize("name", sorted(CONFIGS))
@pytest.mark.parametrize("batch", [1, 5, BATCH_PER_GROUP])
def test_the_inference_form_computes_what_the_trained_network_does(name, batch):
    model = _trained_looking(CONFIGS[name])
    fused = inference_network(model)
    example = TensorBatch.example(model.receptive_field, model.skeleton.num_joints, batch, seed=batch)
    with torch.no_grad():
        pose, root = model(example)
        fused_pose, fused_root = fused(example)
    assert torch.allclose(fused_pose, pose, atol=1e-5, rtol=0)
    assert torch.allclose(fused_root, root, atol=1e-5, rtol=1e-6)


def test_the_inference_form_has_no_batch_norm_or_dropout_and_stacks_the_rie_groups():
    fused = inference_network(_trained_looking(PRESETS["ray3d"]))
    assert isinstance(fused.pose_net, StackedRIEBranch) and isinstance(fused.trajectory_net, StackedRIEBranch)
    stacked = [m for branch in (fused.pose_net, fused.trajectory_net)
               for m in branch.children() if m is not branch.per_group]
    assert not [m for part in stacked for m in part.modules() if isinstance(m, (BatchNorm, Dropout))]
    assert not [m for m in fused.modules() if isinstance(m, (BatchNorm, Dropout, torch.nn.Dropout))]
    assert fused.pose_net.expand.weight.shape[0] == 5  # the five groups in one product


def test_the_trained_network_is_left_as_it_was_and_the_form_cannot_be_trained():
    model = _trained_looking(PRESETS["ray3d"])
    before = {k: v.clone() for k, v in model.state_dict().items()}
    fused = inference_network(model)
    assert all(torch.equal(before[k], v) for k, v in model.state_dict().items())
    assert any(isinstance(m, BatchNorm) for m in model.modules())
    model.train()  # still trainable
    assert inference_network(fused) is fused  # already in inference form
    with pytest.raises(ValueError, match="cannot be trained"):
        fused.train()


def test_lifting_with_the_shipped_model_matches_the_trained_form_in_metres():
    camera = cameras.h36m("S9", "54138969")
    pixels = camera.project(demo_clip()[:300:2])
    lifter = Lifter.load("ray3d")
    assert getattr(lifter.model, "inference_form", False)
    lifted = lifter.lift(pixels, camera, chunk=130).joints  # chunks of 130 and 20 frames: both paths
    lifter.runner.model = load_model("ray3d")[0]  # the network as trained, batch norms and per-group layers
    expected = lifter.lift(pixels, camera, chunk=130).joints
    assert np.abs(lifted - expected).max() < 1e-5


@pytest.mark.parametrize("batch", [3, BATCH_PER_GROUP + 1])
def test_torchscript_runs_the_inference_form_at_small_and_large_batches(batch):
    model = _trained_looking(PRESETS["ray3d"])
    traced = TorchScriptLiftingModel(model)
    example = TensorBatch.example(model.receptive_field, 17, batch, seed=7)
    with torch.no_grad():
        pose, root = model(example)
    traced_pose, traced_root = traced(example)
    assert torch.allclose(traced_pose, pose, atol=1e-5) and torch.allclose(traced_root, root, atol=1e-5)


def test_a_config_change_keeps_the_two_forms_equal_for_the_causal_window():
    config = dataclasses.replace(PRESETS["ray3d-causal"], root_kernels=(3, 3, 3), name="causal-root27")
    model = _trained_looking(config)
    example = TensorBatch.example(model.receptive_field, 17, 4, seed=11)
    with torch.no_grad():
        assert torch.allclose(inference_network(model)(example)[1], model(example)[1], atol=1e-5)
