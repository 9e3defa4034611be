"""RFRH baseline: exact at the assumed height, clear errors where the ray never gets there."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import random_camera

from ray3d import Camera, InputError, cameras
from ray3d.baselines.rfrh import DEFAULT_ROOT_HEIGHT_M, rfrh_root


@pytest.mark.parametrize("camera", cameras.h36m_all()[::5], ids=lambda c: c.name)
def test_exact_when_the_root_is_at_the_assumed_height(camera):
    rng = np.random.default_rng(0)
    roots = np.column_stack([rng.uniform(-1.5, 1.5, (50, 2)), np.full(50, DEFAULT_ROOT_HEIGHT_M)])
    np.testing.assert_allclose(rfrh_root(camera.project(roots), camera), roots, atol=1e-9)


def test_other_heights_and_torch(rng):
    camera = random_camera(rng, distortion=True)
    heading = camera.R[2] * np.array([1.0, 1.0, 0.0])  # the optical axis, levelled
    root = camera.center + 4.0 * heading / np.linalg.norm(heading)
    root[2] = 1.1
    pixels = torch.tensor(camera.project(root[None]), dtype=torch.float64)
    estimate = rfrh_root(pixels, camera, root_height=1.1)
    assert isinstance(estimate, torch.Tensor)
    np.testing.assert_allclose(estimate.numpy()[0], root, atol=1e-8)
    # A crouching person (root lower than assumed) is placed too far away along the same ray.
    lower = root.copy()
    lower[2] = 0.6
    placed = rfrh_root(camera.project(lower[None]), camera, root_height=1.1)[0]
    assert placed[2] == pytest.approx(1.1)
    assert np.linalg.norm(placed - lower) > 0.1


def test_ray_that_never_reaches_the_height_raises_or_gives_nan():
    # A level camera 1.5 m high: pixels above the horizon look up and never come down to 0.9395 m.
    camera = Camera.from_pose([0.0, 0.0, 1.5], yaw=0.0, pitch=0.0, roll=0.0, fx=1000, fy=1000, cx=500, cy=500,
                              image_size=(1000, 1000))
    pixels = np.array([[500.0, 800.0], [500.0, 200.0], [500.0, 500.0]])
    with pytest.raises(InputError, match=r"rays of 2 root pixel\(s\).*never reach the height 0.9395 m"):
        rfrh_root(pixels, camera)
    out = rfrh_root(pixels, camera, unreachable="nan")
    assert np.isfinite(out[0]).all() and np.isnan(out[1:]).all()
