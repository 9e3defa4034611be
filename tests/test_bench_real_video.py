"""``ray3d bench real-video`` end to end on generated detections, and the physical checks on known motion."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ray3d import cameras
from ray3d.bench.physical import track_checks
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult


def _walk(frames=90, fps=30.0, speed=1.2):
    clip = demo_clip()[:1].repeat(frames, axis=0)  # one pose carried along at a steady speed
    clip[..., 0] += speed * np.arange(frames)[:, None] / fps
    clip[..., 2] += 0.07 - clip[:, [3, 6], 2].min(1)[:, None]
    return clip


def test_the_checks_of_a_person_gliding_on_the_floor():
    clip = _walk()
    interpolated = np.zeros(clip.shape[:2], dtype=bool)
    interpolated[40:50] = True  # frames filled in across a gap do not count
    checks = track_checks(LiftResult(clip, interpolated, 30.0, np.arange(len(clip))))
    assert checks["frames"] == 80 and checks["ankle_on_floor_fraction"] == 1.0
    assert checks["walking_speed_1s_m_s"] == pytest.approx(1.2) and checks["speed_p90_m_s"] == pytest.approx(1.2)
    assert (checks["bone_length_cv"] == pytest.approx(0.0, abs=1e-9)
            and checks["jitter_m_s2"] == pytest.approx(0.0, abs=1e-6))
    assert checks["foot_skating_m_s"] == pytest.approx(1.2)  # it glides: the planted foot slides at the body's speed
    assert checks["stature_m"] == pytest.approx((clip[0, 10, 2] - 0.07) / 0.873)


def test_the_bench_checks_a_video_s_detections_and_emulated_mocap(mocap_dir, tmp_path, capsys):
    camera = cameras.h36m("S9", "54138969")
    pixels = camera.project(_walk(60))
    detections = tmp_path / "keypoints.json"
    detections.write_text(json.dumps({"layout": "h36m17", "fps": 30, "detections": [
        {"frame": i, "track": 0, "keypoints": p.tolist()} for i, p in enumerate(pixels)]}))
    out = tmp_path / "bench"
    assert main(["bench", "real-video", "--keypoints", str(detections), "--camera", "h36m:S9:54138969",
                 "--out", str(out), "--pairs", "2", "--data-dir", str(mocap_dir)]) == 0
    document = json.loads((out / "real-video.json").read_text())
    assert {r["refine"] for r in document["video_rows"]} == {False, True}
    assert len(document["emulated_rows"]) >= 2 and all(r["mrpe_mm"] > 0 for r in document["emulated_rows"])
    table = (out / "real-video.md").read_text()
    assert "keypoints.json (no ground truth)" in table and "detector-emulated mocap test split" in table
    assert main(["bench", "real-video", "--keypoints", str(detections), "--out", str(out)]) == 2
    assert "need --camera" in capsys.readouterr().err
