"""ONNX export and the ONNX Runtime backend give the torch results."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import Lifter, cameras
from ray3d.cli import main
from ray3d.demo import demo_clip

onnxruntime = pytest.importorskip("onnxruntime", reason="the onnx extra is not installed: pip install 'ray3d[onnx]'")


@pytest.mark.parametrize("name", ["ray3d", "videopose3d", "rie", "ray3d-causal", "poseformer"])
def test_onnx_backend_equals_torch_within_a_tenth_of_a_millimetre(name):
    camera = cameras.h36m("S9", "54138969")
    truth = demo_clip()[:40]
    pixels = camera.project(truth)
    torch_result = Lifter.load(name).lift(pixels, camera, flip_test=True)
    onnx_result = Lifter.load(name, backend="onnx").lift(pixels, camera, flip_test=True)
    assert np.abs(onnx_result.joints - torch_result.joints).max() < 1e-4


def test_export_cli_writes_a_runnable_model(tmp_path, capsys):
    out = tmp_path / "ray3d.onnx"
    assert main(["export", "--onnx", "--out", str(out)]) == 0
    session = onnxruntime.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    names = {i.name for i in session.get_inputs()}
    assert {"rays", "camera_params"} <= names
    assert main(["export", "--onnx", "--out", str(out)]) == 2  # refuses to overwrite
    assert "already exists" in capsys.readouterr().err
