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


def test_only_pixel_input_traces_are_bound_to_their_image_width():
    from ray3d.models import PRESETS, LiftingNetwork
    from ray3d.models.backends import TorchScriptLiftingModel
    from ray3d.models.tensor_batch import TensorBatch

    for name, bound in (("ray3d", False), ("videopose3d", True)):  # rays in, pixels in
        model = LiftingNetwork(PRESETS[name]).eval()
        traced = TorchScriptLiftingModel(model, image_width=1000.0, batches=(2,))
        wider = TensorBatch.example(model.receptive_field, 17, 3, image_width=1280.0)
        if bound:
            with pytest.raises(InputError, match="built for 1000-pixel-wide images, got 1280"):
                traced(wider)
        else:
            assert traced(wider)[0].shape == (3, 17, 3)
