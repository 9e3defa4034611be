"""Reduced precision (``models.precision``, ``Lifter.load(precision=...)``, ``--precision``) and the small-batch
trace a lifter switches to."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from ray3d import cameras
from ray3d.cli import main
from ray3d.demo import DEMO_CAMERA, demo_clip
from ray3d.errors import InputError
from ray3d.io.world import read_world
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.runner import SMALL_BATCHES_BEFORE_TRACING
from ray3d.models import PRESETS, LiftingNetwork
from ray3d.models.inference import inference_network
from ray3d.models.precision import (
    Bfloat16Products,
    Int8Products,
    ReducedPrecisionNetwork,
    input_layer_names,
    output_layer_names,
)
from ray3d.models.tensor_batch import TensorBatch


@pytest.fixture(scope="module")
def demo():
    camera = cameras.h36m(*DEMO_CAMERA)
    truth = demo_clip()
    return camera, truth, camera.project(truth)


@pytest.fixture(scope="module")
def fp32_joints(demo):
    camera, _, pixels = demo
    return Lifter.load("ray3d").lift(pixels, camera, refine=False).joints


# Stated in models/precision.py and docs/RESULTS.md: on the demo clip through its Human3.6M camera (shipped ray3d,
# 242 frames: the batched path) bf16 moves a joint by 0.5 mm on average (2.4 at most), int8 by 3.3 (15 at most);
# Abs-MPJPE changes by 0.2-0.3 mm.
@pytest.mark.parametrize("precision, mean_mm, most_mm", [("bf16", 2.0, 10.0), ("int8", 8.0, 40.0)])
def test_reduced_precision_agrees_with_fp32_on_the_demo_clip(demo, fp32_joints, precision, mean_mm, most_mm):
    camera, truth, pixels = demo
    lifter = Lifter.load("ray3d", precision=precision)
    assert lifter.runner.precision == precision and isinstance(lifter.model, ReducedPrecisionNetwork)
    joints = lifter.lift(pixels, camera, refine=False).joints
    apart = 1000 * np.linalg.norm(joints - fp32_joints, axis=-1)
    assert 0 < apart.mean() < mean_mm and apart.max() < most_mm  # it did change, and by little
    error = [1000 * np.linalg.norm(j - truth, axis=-1).mean() for j in (fp32_joints, joints)]
    assert abs(error[1] - error[0]) < 1.0


def test_only_hidden_layers_are_reduced_inputs_and_outputs_keep_float32():
    model = LiftingNetwork(PRESETS["ray3d"]).eval()
    folded = inference_network(model)
    outputs = output_layer_names(folded)
    assert "trajectory_net.per_group.head.2" in outputs and "pose_net.decode_out" in outputs
    inputs = input_layer_names(folded, [TensorBatch.example(folded.receptive_field, 17, n) for n in (1, 128)])
    assert "pose_net.expand" in inputs and "pose_camera.net.0" in inputs  # the stacked path's and the camera's
    assert "pose_net.per_group.backbone.encoders.torso.expand.0" in inputs
    assert not any(".blocks." in name for name in inputs + outputs)
    for precision, reduced in (("bf16", Bfloat16Products), ("int8", Int8Products)):
        network = ReducedPrecisionNetwork(model, precision).network
        hidden = {name for name, m in network.named_modules() if isinstance(m, reduced)}
        assert any(".blocks." in name for name in hidden) and any(".decoders." in name for name in hidden)
        assert not hidden & set(inputs + outputs)
        for name in inputs + outputs:
            if name in ("pose_net.expand", "trajectory_net.expand", "pose_net.decode_out"):
                continue  # stacked layers (buffers, no parameters)
            assert network.get_submodule(name).weight.dtype == torch.float32, name


def test_a_reduced_network_cannot_be_trained_and_attention_keeps_float32():
    network = ReducedPrecisionNetwork(LiftingNetwork(PRESETS["poseformer"]).eval(), "int8")
    with pytest.raises(ValueError, match="cannot be trained"):
        network.train()
    for module in network.network.modules():
        if isinstance(module, torch.nn.MultiheadAttention):
            assert module.out_proj.weight.dtype == torch.float32
    batch = TensorBatch.example(network.receptive_field, 17, 4)
    pose, root = network(batch)
    assert pose.dtype == root.dtype == torch.float32 and torch.isfinite(pose).all()


def test_bad_precision_and_reduced_precision_off_the_cpu_torch_path_are_refused():
    with pytest.raises(InputError, match="precision: 'fp16' is not one of fp32, bf16, int8"):
        Lifter.load("ray3d", precision="fp16")
    with pytest.raises(InputError, match="torch backend on the CPU"):
        Lifter.load("ray3d", backend="torchscript", precision="int8")


def test_a_lifter_given_small_batches_runs_them_traced_with_the_same_answer(demo):
    camera, _, pixels = demo
    lifter = Lifter.load("ray3d")
    stream = lifter.stream(camera, wait_for_future=False)
    answers = [stream.push(frame) for frame in pixels[:12]]
    runner = lifter.runner
    assert runner._small_batch_runner is not None and runner._small_batches >= SMALL_BATCHES_BEFORE_TRACING
    eager = Lifter.load("ray3d")
    eager.runner._traceable = False  # the network itself, every time
    reference = eager.stream(camera, wait_for_future=False)
    expected = [reference.push(frame) for frame in pixels[:12]]
    for got, want in zip(answers, expected):
        if want is None:
            assert got is None
        else:
            np.testing.assert_allclose(got, want, atol=1e-5)  # metres
    big = Lifter.load("ray3d")
    big.lift(pixels, camera, refine=False)  # one batch of 242 windows: never traced
    assert big.runner._small_batch_runner is None
    live = Lifter.load("ray3d").runner
    live.prepare_small_batches()  # ray3d live: traced before frames arrive
    assert live._small_batch_runner is not None and live._network_for(1) is live._small_batch_runner
    reduced = Lifter.load("ray3d", precision="int8").runner
    reduced.prepare_small_batches()  # a reduced-precision network is not traced
    assert reduced._small_batch_runner is None and reduced._network_for(1) is reduced.model


def test_evaluate_reports_what_a_reduced_precision_costs(tmp_path, capsys):
    out = tmp_path / "int8.json"
    assert main(["evaluate", "--checkpoint", "ray3d", "--cameras", "h36m", "--frame-stride", "64", "--precision",
                 "int8", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["precision"] == "int8"
    assert set(result["change_from_fp32_mm"]) == {"mpjpe_mm", "p_mpjpe_mm", "abs_mpjpe_mm", "mrpe_mm"}
    assert abs(result["change_from_fp32_mm"]["abs_mpjpe_mm"]) < 5.0
    assert "int8 against fp32" in capsys.readouterr().out
    assert main(["evaluate", "--checkpoint", "rfrh", "--cameras", "h36m", "--precision", "bf16"]) == 2
    assert "rfrh has none" in capsys.readouterr().err


def test_lift_on_the_command_line_in_int8(tmp_path, demo):
    camera, _, pixels = demo
    keypoints = tmp_path / "keypoints.npz"
    np.savez(keypoints, keypoints=pixels[:60], layout="h36m17", fps=50.0)
    spec = f"h36m:{DEMO_CAMERA[0]}:{DEMO_CAMERA[1]}"
    out = tmp_path / "world.json"
    assert main(["lift", "--keypoints", str(keypoints), "--camera", spec, "--precision", "int8",
                 "--out", str(out)]) == 0
    assert read_world(out).track().joints.shape == (60, 17, 3)
    with pytest.raises(SystemExit) as refused:  # argparse's choices: one line, exit code 2
        main(["lift", "--keypoints", str(keypoints), "--camera", spec, "--precision", "fp16",
              "--out", str(tmp_path / "other.json")])
    assert refused.value.code == 2
