"""The evaluation protocol: exact predictions score 0 mm, RFRH at the true height scores 0, JSON keys."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ray3d import evaluate as evaluation
from ray3d.cli import main
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import grid
from ray3d.errors import InputError
from ray3d.models.presets import preset


def _standing_clip(frames=20, pelvis_height=0.9395):
    rng = np.random.default_rng(0)
    pose = rng.normal(0, 0.15, (17, 3))
    pose[0] = 0.0
    clip = np.tile(pose, (frames, 1, 1)) + np.array([0.0, 0.0, pelvis_height])
    clip[:, :, 0] += np.linspace(-0.5, 0.5, frames)[:, None]
    return clip.astype(np.float32)


@pytest.mark.parametrize("causal", [False, True])
def test_a_model_that_outputs_the_truth_scores_zero(monkeypatch, causal):
    target = 8 if causal else 4
    monkeypatch.setattr(evaluation, "predict_windows",
                        lambda model, windows, camera, flip_test=False, **options: windows[:, target])

    class Oracle:
        receptive_field = 9
        config = preset("ray3d", causal=causal)

    motion = MotionSet.from_clips([_standing_clip(), _standing_clip(30)], clip_id=["a", "b"])
    result = evaluation.evaluate(Oracle(), motion, grid("extrinsic-test")[:3])
    for key in evaluation.METRICS:
        assert result[key] == pytest.approx(0.0, abs=1e-9)
        assert all(v[key] == pytest.approx(0.0, abs=1e-9) for v in result["per_camera"].values())
    assert result["frames"] == 3 * 50 and set(result["per_clip"]) == {"a", "b"}


def test_the_14_joint_score_ignores_spine_thorax_and_neck(monkeypatch):
    def wrong_trunk(model, windows, camera, flip_test=False, **options):
        predicted = windows[:, 4].copy()
        predicted[:, [7, 8, 9]] += 0.1  # spine, thorax, neck/nose
        return predicted

    monkeypatch.setattr(evaluation, "predict_windows", wrong_trunk)

    class Model:
        receptive_field = 9
        config = preset("ray3d")

    motion = MotionSet.from_clips([_standing_clip()], clip_id=["a"])
    full = evaluation.evaluate(Model(), motion, grid("h36m")[:2])
    common = evaluation.evaluate(Model(), motion, grid("h36m")[:2], joints="h36m14")
    assert full["mpjpe_mm"] == pytest.approx(3 / 17 * 100 * np.sqrt(3), rel=1e-6)
    assert common["mpjpe_mm"] == pytest.approx(0.0, abs=1e-9) and common["joints"] == "h36m14"


def test_rfrh_is_exact_when_the_pelvis_is_at_its_height():
    motion = MotionSet.from_clips([_standing_clip()], clip_id=["stand"])
    result = evaluation.evaluate("rfrh", motion, grid("h36m")[:4])
    assert result["mrpe_mm"] == pytest.approx(0.0, abs=1e-3)
    assert result["abs_mpjpe_mm"] is None  # RFRH places the root only


def test_2d_noise_moves_rfrh_off_the_exact_answer_reproducibly():
    motion = MotionSet.from_clips([_standing_clip()], clip_id=["stand"])
    cameras = grid("h36m")[:2]
    noisy = evaluation.evaluate("rfrh", motion, cameras, noise_px=5.0, seed=3)
    assert noisy["mrpe_mm"] > 1.0 and noisy["noise_px"] == 5.0
    assert evaluation.evaluate("rfrh", motion, cameras, noise_px=5.0, seed=3)["mrpe_mm"] == noisy["mrpe_mm"]
    assert evaluation.evaluate("rfrh", motion, cameras)["mrpe_mm"] == pytest.approx(0.0, abs=1e-3)


def test_evaluate_cli_writes_the_documented_json(tmp_path, capsys):
    motion = MotionSet.from_clips([_standing_clip(), _standing_clip(pelvis_height=0.7)], clip_id=["a", "b"])
    motion.save(tmp_path / "mine.npz")
    out = tmp_path / "result.json"
    assert main(["evaluate", "--checkpoint", "rfrh", "--mocap", str(tmp_path / "mine.npz"), "--cameras", "h36m",
                 "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert {"mpjpe_mm", "p_mpjpe_mm", "abs_mpjpe_mm", "mrpe_mm", "frames", "per_camera"} <= set(result)
    assert result["frames"] == 40 * len(result["per_camera"]) and result["mrpe_mm"] > 10
    assert "overall" in capsys.readouterr().out
    assert main(["evaluate", "--checkpoint", "nonexistent-model", "--mocap", str(tmp_path / "mine.npz"),
                 "--cameras", "h36m"]) == 2


def test_a_wrong_camera_and_a_smaller_body_change_the_errors():
    from ray3d import Camera

    motion = MotionSet.from_clips([_standing_clip()], clip_id=["stand"])
    camera = grid("h36m")[0]
    exact = evaluation.evaluate("rfrh", motion, [camera])
    assert exact["mrpe_mm"] == pytest.approx(0.0, abs=1e-3)
    lower = Camera(camera.K, camera.dist, camera.R, camera.t + camera.R @ [0.0, 0.0, 0.2], camera.image_size)
    told_wrong = evaluation.evaluate("rfrh", motion, [camera], given_cameras=[lower])
    assert told_wrong["mrpe_mm"] > 50  # told the camera is 20 cm lower than it is
    smaller = evaluation.evaluate("rfrh", motion, [camera], bone_scale=0.8)
    assert smaller["mrpe_mm"] > 10  # a smaller body's pelvis is lower than the assumed height


def test_refined_evaluation_lifts_each_clip_as_a_track(monkeypatch):
    """A model that puts everyone 15 % too close (within what the floor test allows 13 m away): the refinement,
    given the true rays, brings them back."""
    from ray3d.refine import RefineConfig, scale_about

    camera = grid("far-test")[0]

    def too_close(model, windows, cam, flip_test=False, return_pixels=False, **options):
        truth = windows[:, 4]
        wrong = scale_about(truth, cam.center, np.full(len(truth), 0.85))
        return (wrong, cam.project(truth)) if return_pixels else wrong

    monkeypatch.setattr(evaluation, "predict_windows", too_close)

    class Model:
        receptive_field = 9
        config = preset("ray3d")

    from ray3d.demo import demo_clip

    motion = MotionSet.from_clips([demo_clip()[:90].astype(np.float32)], clip_id=["a"])  # a person, not a blob
    plain = evaluation.evaluate(Model(), motion, [camera])
    refined = evaluation.evaluate(Model(), motion, [camera], refine=True)
    assert refined["refine"] and plain["mrpe_mm"] > 2000 and refined["mrpe_mm"] < 0.35 * plain["mrpe_mm"]
    assert refined["refine_config"]["keypoint_error"] == 0.0  # GT 2D: exact rays
    trusting = evaluation.evaluate(Model(), motion, [camera], refine=RefineConfig(depth_sd=(1e-6, 0.0)))
    assert trusting["refine_config"]["depth_sd"] == (1e-6, 0.0)
    assert trusting["mrpe_mm"] > 0.9 * plain["mrpe_mm"]  # told the network's depth is exact, it keeps it
    with pytest.raises(InputError, match="rfrh predicts only the root"):
        evaluation.evaluate("rfrh", motion, [camera], refine=True)
