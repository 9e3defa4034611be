"""Shared fixtures: random but valid cameras and points in front of them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ray3d import Camera


def random_camera(rng: np.random.Generator, distortion: bool = False, roll: bool = True) -> Camera:
    """A camera 0.5-4 m high, pitch -10..60 deg, any yaw, up to 8 deg roll, looking at the capture area."""
    dist = None
    if distortion:
        dist = [rng.uniform(-0.25, -0.1), rng.uniform(0.05, 0.25), rng.uniform(-3e-3, 3e-3),
                rng.uniform(-3e-3, 3e-3), rng.uniform(-0.01, 0.01)]
    return Camera.from_pose(
        center=[rng.uniform(-6, 6), rng.uniform(-6, 6), rng.uniform(0.5, 4.0)],
        yaw=rng.uniform(-np.pi, np.pi), pitch=np.radians(rng.uniform(-10, 60)),
        roll=np.radians(rng.uniform(-8, 8)) if roll else 0.0,
        fx=rng.uniform(500, 2000), fy=rng.uniform(500, 2000), cx=rng.uniform(300, 700), cy=rng.uniform(300, 700),
        image_size=(1000, 1000), dist=dist)


def points_in_front(camera: Camera, rng: np.random.Generator, n: int, max_xy: float = 0.6) -> np.ndarray:
    """(n, 3) world points 1-12 m in front of ``camera`` within a modest field of view."""
    depth = rng.uniform(1, 12, n)
    xy = rng.uniform(-max_xy, max_xy, (n, 2)) * depth[:, None]
    return camera.camera_to_world(np.column_stack([xy, depth]))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


SHARED_MOCAP = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "mocap"


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    """The shipped mocap folder beside the repository (CI has it); tests that need it skip without it."""
    if not (SHARED_MOCAP / "cmu_h36m17.npz").is_file():
        pytest.skip(f"shared mocap data not found at {SHARED_MOCAP}")
    return SHARED_MOCAP.resolve()


@pytest.fixture(scope="session")
def test_motion(mocap_dir):
    from ray3d.data.motion import load_shipped

    return load_shipped(mocap_dir, "test")


@pytest.fixture(scope="session")
def tiny_data_dir(mocap_dir, tmp_path_factory) -> Path:
    """A small copy of the shipped CMU file: a few short clips of each split, for training tests."""
    from ray3d.data.motion import MotionSet, split_of

    motion = MotionSet.load(mocap_dir / "cmu_h36m17.npz")
    splits = np.array([split_of(s) for s in motion.clips["orig_subject"]])
    keep = np.zeros(motion.num_clips, dtype=bool)
    for split in ("train", "validation", "test"):
        keep[np.flatnonzero((splits == split) & (motion.clip_lengths() < 400))[:3]] = True
    folder = tmp_path_factory.mktemp("tiny_mocap")
    motion.select(keep).save(folder / "cmu_h36m17.npz")
    return folder


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory) -> Path:
    """An untrained tiny Ray3D checkpoint: enough to exercise the lifting plumbing without shipped weights."""
    import torch

    from ray3d.checkpoints import save_checkpoint
    from ray3d.models import LiftingNetwork, preset

    torch.manual_seed(0)
    model = LiftingNetwork(preset("ray3d", channels=16, hidden=32)).eval()
    path = tmp_path_factory.mktemp("tiny_model") / "tiny.safetensors"
    save_checkpoint(path, {f"model.{k}": v for k, v in model.state_dict().items()},
                    {"model": model.config, "trained_on": "nothing (untrained test model)"})
    return path
