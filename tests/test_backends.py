"""The TorchScript backend gives the torch results, in batches and frame by frame."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import InputError, Lifter, cameras
from ray3d.demo import demo_clip


@pytest.mark.parametrize("name", ["ray3d", "videopose3d", "poseformer"])
def test_torchscript_backend_equals_torch_within_a_tenth_of_a_millimetre(name):
    camera = cameras.h36m("S9", "54138969")
    pixels = camera.project(demo_clip()[:40])
    eager = Lifter.load(name).lift(pixels, camera, flip_test=True).joints
    scripted = Lifter.load(name, backend="torchscript")
    assert np.abs(scripted.lift(pixels, camera, flip_test=True).joints - eager).max() < 1e-4
    stream = scripted.stream(camera)
    streamed = [stream.push(p) for p in pixels]
    streamed = np.stack([s for s in streamed if s is not None] + stream.flush())
    assert np.abs(streamed - Lifter.load(name).lift(pixels, camera, refine=False).joints).max() < 1e-4


def test_unknown_backend_is_refused():
    with pytest.raises(InputError, match="unknown backend 'tensorrt'"):
        Lifter.load("ray3d", backend="tensorrt")
