"""Networks: shapes, receptive fields, joint layouts, the centre frame, flip equivariance of the plumbing."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from ray3d.models import PRESETS, LiftingNetwork, TensorBatch, preset
from ray3d.models.blocks import TemporalEncoder
from ray3d.models.network import ModelConfig, count_parameters, flops_per_frame
from ray3d.models.rie import RIEBackbone, rie_encodings
from ray3d.skeleton import H36M17, LAYOUTS

TINY = dict(channels=16, hidden=32)


def _batch(frames: int, joints: int = 17, size: int = 4) -> TensorBatch:
    torch.manual_seed(0)
    rays = torch.randn(size, frames, joints, 3) * 0.2 + torch.tensor([0.0, 0.3, 1.0])
    pixels = torch.rand(size, frames, joints, 2) * 1000
    return TensorBatch(pixels, rays, torch.tensor([[1.5, 0.2]] * size), torch.tensor([[1000.0, 1000, 500, 500]] * size),
                       torch.full((size,), 0.05), 1000.0)


@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_outputs_pose_and_root(name):
    model = LiftingNetwork(dataclasses.replace(PRESETS[name], **TINY)).eval()
    pose, root = model(_batch(model.receptive_field))
    assert pose.shape == (4, 17, 3) and root.shape == (4, 3)
    assert torch.all(pose[:, 0] == 0)
    assert count_parameters(model) > 0 and flops_per_frame(model) > 0


@pytest.mark.parametrize("kernels, frames", [((1,), 1), ((3, 3), 9), ((3, 3, 3), 27), ((3, 3, 3, 3), 81),
                                             ((3, 3, 3, 3, 3), 243)])
def test_receptive_field_is_the_product_of_kernel_widths(kernels, frames):
    model = LiftingNetwork(preset("ray3d", kernels=kernels, **TINY)).eval()
    assert model.receptive_field == frames
    assert model(_batch(frames, size=2))[0].shape == (2, 17, 3)
    with pytest.raises(ValueError, match=f"expected windows of {frames} frames"):
        model(_batch(frames + 2, size=2))


@pytest.mark.parametrize("layout", ["h36m17", "h36m14", "humaneva15"])
def test_joint_layouts(layout):
    skeleton = LAYOUTS[layout]
    for name in ("ray3d", "videopose3d", "rie"):
        config = preset(name, layout=layout, **TINY)
        model = LiftingNetwork(config).eval()
        pose, root = model(_batch(9, skeleton.num_joints))
        assert pose.shape == (4, skeleton.num_joints, 3) and root.shape == (4, 3)
    groups = RIEBackbone(skeleton, 3, 8, 8, (3, 3), 0.0, False).groups
    assert sorted(j for joints in groups.values() for j in joints) == list(range(skeleton.num_joints))
    assert all(skeleton.joint_names[j].startswith("l_") for j in groups["left_leg"] + groups["left_arm"])


def test_group_decoders_write_their_own_joints():
    """Zeroing one group's decoder zeroes exactly that group's joints (relative to the root)."""
    model = LiftingNetwork(preset("ray3d", layout="humaneva15", **TINY)).eval()
    decoder = model.pose_net.decoders["left_arm"][-1]
    with torch.no_grad():
        decoder.weight.zero_()
        decoder.bias.zero_()
    raw = model.pose_net(model.network_input(_batch(9, 15)),
                         _batch(9, 15).rays[..., 1] / 1.5, model.pose_camera(_batch(9, 15).camera_params))
    for joint in LAYOUTS["humaneva15"].groups["left_arm"]:
        assert torch.all(raw[:, joint] == 0)
    others = [j for j in range(15) if j not in LAYOUTS["humaneva15"].groups["left_arm"]]
    assert torch.all(raw[:, others].abs().sum(-1) > 0)


def test_centre_frame_drives_the_global_branch_and_the_temporal_encoding():
    backbone = RIEBackbone(H36M17, 3, 8, 16, (3, 3), 0.0, False).eval()
    x = torch.randn(2, 9, 17, 3)
    perturbed = x.clone()
    perturbed[:, 0] += 1.0  # a non-centre frame
    with torch.no_grad():
        _, global_a = backbone(x)
        _, global_b = backbone(perturbed)
    assert torch.equal(global_a, global_b)
    encoded_a, encoded_b = rie_encodings(x), rie_encodings(perturbed)
    assert not torch.equal(encoded_a[:, 0], encoded_b[:, 0])          # the perturbed frame's encoding changes
    assert torch.equal(encoded_a[:, 4, :, 6:], torch.zeros_like(encoded_a[:, 4, :, 6:]))  # centre = frame 4 of 9
    centre = x.clone()
    centre[:, 4] += 1.0
    with torch.no_grad():
        assert not torch.equal(backbone(centre)[1], global_a)


@pytest.mark.parametrize("causal", [False, True])
def test_temporal_encoder_aligns_its_residual_with_the_target_frame(causal):
    encoder = TemporalEncoder(2, 4, (3, 3), 0.0, causal=causal).eval()
    assert encoder.receptive_field == 9
    with torch.no_grad():
        for block in encoder.blocks:  # residual blocks that add nothing: only the residual path is left
            block[0][0].weight.zero_()
        middle = torch.zeros(5, 9, 2)
        middle[:, 3:6] = torch.randn(5, 3, 2)   # only the middle three frames move
        last = torch.zeros(5, 9, 2)
        last[:, 6:] = torch.randn(5, 3, 2)      # only the last three frames move
        centred_sees_middle = encoder(middle).abs().sum() > 0
        causal_sees_last = encoder(last).abs().sum() > 0
    assert encoder(torch.randn(5, 9, 2)).shape == (5, 4)
    assert centred_sees_middle != causal and causal_sees_last == causal


def test_frame_group_linear_is_a_strided_convolution_and_loads_its_weights():
    from ray3d.models.blocks import FrameGroupLinear

    conv = torch.nn.Conv1d(5, 7, 3, stride=3, bias=False)
    layer = FrameGroupLinear(5, 7, 3)
    layer.load_state_dict(conv.state_dict())  # an older checkpoint's Conv1d weights
    x = torch.randn(4, 9, 5)
    torch.testing.assert_close(layer(x), conv(x.transpose(1, 2)).transpose(1, 2))


@pytest.mark.parametrize("frames", [1, 9, 27])
def test_poseformer_window_is_its_one_kernel_and_order_matters(frames):
    """The transformer sees exactly its window; its position embeddings make frame and joint order matter."""
    model = LiftingNetwork(preset("poseformer", kernels=(frames,), **TINY)).eval()
    assert model.receptive_field == frames and model.pose_net.backbone.receptive_field == frames
    batch = _batch(frames)
    with torch.no_grad():
        pose, root = model(batch)
        assert pose.shape == (4, 17, 3) and root.shape == (4, 3)
        joints_swapped = dataclasses.replace(batch, pixels=batch.pixels[:, :, [0, 2, 1, *range(3, 17)]])
        assert not torch.allclose(model(joints_swapped)[1], root)
        if frames > 1:
            reversed_frames = dataclasses.replace(batch, pixels=batch.pixels.flip(1))
            assert not torch.allclose(model(reversed_frames)[1], root)
    with pytest.raises(ValueError, match=f"expected windows of {frames} frames"):
        model(_batch(frames + 2))


def test_poseformer_takes_rays_ground_features_and_a_causal_window():
    config = preset("ray3d", backbone="transformer", kernels=(9,), layers=1, causal=True, channels=8, hidden=32)
    model = LiftingNetwork(config).eval()
    with torch.no_grad():
        pose, root = model(_batch(9))
    assert pose.shape == (4, 17, 3) and torch.isfinite(root).all()
    with pytest.raises(ValueError, match="window is one number"):
        preset("poseformer", kernels=(3, 3))
    with pytest.raises(ValueError, match="multiple of 8"):
        LiftingNetwork(preset("poseformer", channels=12))


def test_poseformer_trains_one_step_and_scores_in_flops():
    model = LiftingNetwork(preset("poseformer", **TINY))
    before = [p.detach().clone() for p in model.parameters()]
    pose, root = model(_batch(9))
    (pose.square().mean() + root.square().mean()).backward()
    torch.optim.SGD(model.parameters(), lr=0.1).step()
    moved = [not torch.equal(a, b.detach()) for a, b in zip(before, model.parameters())]
    assert all(moved)  # every parameter, the position embeddings and frame weights among them, is trained
    one_layer = flops_per_frame(LiftingNetwork(preset("poseformer", **{**TINY, "layers": 1})))
    assert flops_per_frame(model) > 1.5 * one_layer  # the transformer layers are counted


def test_config_rejects_inconsistent_combinations():
    with pytest.raises(ValueError, match="an NCS output needs ncs_rays input"):
        ModelConfig(input="pixels", output_frame="ncs", ground_features=False)
    with pytest.raises(ValueError, match="ray_depth needs ray input"):
        ModelConfig(input="pixels", output_frame="camera", ground_features=False, root="ray_depth")


@pytest.mark.parametrize("name", ["ray3d", "poseformer"])
def test_flip_test_is_consistent_for_a_mirror_symmetric_input(name):
    model = LiftingNetwork(preset(name, **TINY)).eval()
    batch = _batch(9)
    with torch.no_grad():
        pose, root = model.predict(batch, flip_test=True)
        pose_f, root_f = model.predict(batch.flipped(model.skeleton), flip_test=True)
    perm = list(model.skeleton.flip_permutation)
    mirror = torch.tensor([-1.0, 1.0, 1.0])
    torch.testing.assert_close(pose_f, pose[:, perm] * mirror, atol=1e-5, rtol=1e-4)
    torch.testing.assert_close(root_f, root * mirror, atol=1e-5, rtol=1e-4)


def test_gravity_aligned_model_round_trips_its_targets():
    import numpy as np

    from ray3d.data.virtual_cameras import CameraRanges, sample_cameras
    from ray3d.geometry import CameraBatch

    model = LiftingNetwork(preset("rie-decoupled", remove_roll=True, **TINY)).eval()
    rng = np.random.default_rng(0)
    cams = sample_cameras(rng.normal(0, 1, (4, 3)) + [0, 0, 1], rng, CameraRanges(roll_deg=5.0))
    assert isinstance(cams, CameraBatch)
    batch = _batch(9)
    batch.camera_params = torch.tensor(np.stack([cams.height, cams.pitch], -1), dtype=torch.float32)
    batch.roll = torch.tensor(cams.roll, dtype=torch.float32)
    root_ncs = torch.randn(4, 3, dtype=torch.float64)
    pose, root = model.targets(batch, torch.zeros(4, 17, 3, dtype=torch.float64), root_ncs)
    params = batch.camera_params.double()
    world = model.to_world(root[:, None], cams, params)[:, 0]
    ncs_model = LiftingNetwork(preset("ray3d", remove_roll=True, **TINY))
    world_from_ncs = ncs_model.to_world(root_ncs[:, None], cams, params)[:, 0]
    torch.testing.assert_close(world, world_from_ncs)


def test_dropout_keeps_the_expectation_and_its_gradient_is_the_mask():
    from ray3d.models.blocks import Dropout

    layer = Dropout(0.25).train()
    x = torch.ones(200_000, requires_grad=True)
    torch.manual_seed(3)
    y = layer(x)
    keep = 1 - round(0.25 * 65536) / 65536
    kept = y != 0
    assert abs(kept.float().mean().item() - keep) < 5e-3  # 0.75 +- 5 standard deviations of 200,000 draws
    assert torch.allclose(y[kept], torch.full_like(y[kept], 1 / keep))
    y.sum().backward()
    assert torch.equal(x.grad, y.detach())  # d y / d x is the scaled mask
    torch.manual_seed(3)
    assert torch.equal(layer(x), y)  # drawn from torch's generator: seeded runs repeat
    assert torch.equal(layer.eval()(x), x) and torch.equal(Dropout(0.0).train()(x), x)
    with pytest.raises(ValueError):
        Dropout(1.0)


@pytest.mark.parametrize("causal", [False, True])
def test_a_longer_root_context_leaves_the_pose_on_its_own_frames(causal):
    config = preset("ray3d", root_kernels=(3, 3, 3), causal=causal, channels=16, hidden=32)
    model = LiftingNetwork(config).eval()
    assert model.receptive_field == config.frames == 27
    assert model.trajectory_net.backbone.receptive_field == 27 and model.pose_net.backbone.receptive_field == 9
    batch = TensorBatch.example(27, 17, 3)
    outside = slice(0, 18) if causal else slice(0, 9)  # frames the pose branch does not see
    changed = dataclasses.replace(batch, rays=batch.rays.clone())
    changed.rays[:, outside] += 0.05
    with torch.no_grad():
        pose, root = model(batch)
        pose_changed, root_changed = model(changed)
    assert torch.equal(pose, pose_changed)
    assert not torch.allclose(root, root_changed)


def test_root_kernels_are_refused_where_there_are_no_kernels_per_branch():
    with pytest.raises(ValueError, match="root_kernels"):
        preset("poseformer", root_kernels=(3, 3, 3))
    with pytest.raises(ValueError, match="odd"):
        preset("ray3d", root_kernels=(2, 3))
