"""The low, level cameras people use: the ``level-test`` set, the no-learning floor guess, and ``ray3d bench
level`` on a few of its cameras."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import Camera, Lifter
from ray3d.baselines.floor_guess import ANKLE_HEIGHT_M, floor_guess
from ray3d.data.virtual_cameras import grid
from ray3d.demo import demo_clip
from ray3d.refine.ankle_plane import APPLY_CHANCE
from ray3d.skeleton import H36M17


def test_the_level_set_is_low_level_near_and_both_ways_up():
    cameras = grid("level-test")
    assert len({c.name for c in cameras}) == len(cameras) == 162
    heights = np.array([c.camera_height for c in cameras])
    pitches = np.degrees([c.pitch for c in cameras])
    distances = np.array([np.linalg.norm(c.center[:2]) for c in cameras])
    assert heights.min() == pytest.approx(0.9) and heights.max() == pytest.approx(1.5)
    assert pitches.min() == pytest.approx(0.0, abs=1e-6) and pitches.max() == pytest.approx(15.0)
    assert distances.min() == pytest.approx(2.5) and distances.max() == pytest.approx(6.0)
    portrait = [c.image_size[1] > c.image_size[0] for c in cameras]
    assert sum(portrait) == len(cameras) // 2 and all(("portrait" in c.name) == p for c, p in zip(cameras, portrait))


def test_the_guess_puts_a_planted_mid_ankle_where_it_stands():
    """Both ankles on the guess's plane: the mid-ankle's ray meets it at their midpoint (within what perspective
    moves a mid-pixel); an unseen ankle, or a ray above the horizon, gives NaN."""
    camera = Camera.from_height_pitch(1.2, 5.0, (1280, 720), hfov_deg=70.0)
    camera = Camera(camera.K, camera.dist, camera.R, camera.t + camera.R @ [4.0, 0.0, 0.0], camera.image_size)
    pose = demo_clip()[:3].astype(np.float64)
    ankles = [H36M17.index("l_ankle"), H36M17.index("r_ankle")]
    pose[:, ankles, 2] = ANKLE_HEIGHT_M
    pixels = camera.project(pose)
    guess = floor_guess(pixels, camera)
    np.testing.assert_allclose(guess[:, :2], pose[:, ankles, :2].mean(axis=1), atol=0.01)
    np.testing.assert_allclose(guess[:, 2], ANKLE_HEIGHT_M)
    pixels[1, ankles[0]] = np.nan
    pixels[2, ankles] = camera.project(np.array([[0.0, 0.0, 5.0], [0.0, 0.1, 5.0]]))  # up in the air
    guess = floor_guess(pixels, camera)
    assert np.isnan(guess[1:]).all() and np.isfinite(guess[0]).all()


def test_bench_level_sets_every_figure_beside_the_guess(tmp_path):
    from ray3d.bench.level import run, summary, write
    from ray3d.data.motion import MotionSet

    clip = demo_clip()[:120]
    motion = MotionSet.from_clips([clip], clip_id=["demo"], subject="s")
    cameras = [c for c in grid("level-test") if ":dist4.0:" in c.name and ":pitch07:" in c.name][:3]
    rows = run(Lifter.load(layout="coco17"), motion, cameras=cameras, max_frames=40)
    assert len(rows) == 3 and all("refused" not in r for r in rows)
    totals = summary(rows)
    assert totals["refined_over_guess"] == pytest.approx(totals["refined_floor_error_m"]
                                                         / totals["guess_floor_error_m"])
    assert 0 <= totals["refined_within_1sd"] <= totals["refined_within_2sd"] <= 1
    files = write(tmp_path, rows)
    assert "the guess" in files[1].read_text()


def test_bench_level_moves_the_cameras_origin_off_the_floor_and_pools_a_cameras_people(tmp_path):
    """``floor_offset_m`` gives the lifter and the guess each camera with its z = 0 above the floor; a camera's
    people are lifted together and the ankle plane they found is reported over the true floor."""
    from ray3d.bench.level import run, summary, write
    from ray3d.data.motion import MotionSet

    clip = demo_clip()[:120]
    motion = MotionSet.from_clips([clip], clip_id=["demo"], subject="s")
    camera = [c for c in grid("level-test") if ":dist4.0:" in c.name and ":pitch07:" in c.name][0]
    rows = run(Lifter.load(layout="coco17"), motion, clips_per_camera=4, cameras=[camera], max_frames=40,
               floor_offset_m=0.15)
    assert len(rows) == 4 and {r["floor_offset_m"] for r in rows} == {0.15}
    assert len({r["ankle_plane_m"] for r in rows}) == 1  # one plane for the camera's people
    totals = summary(rows)
    assert totals["people_per_camera"] == 4 and totals["floor_offset_m"] == 0.15
    # Reported over the true floor, not over the given z = 0: where four people cannot show the file's floor off
    # beyond reasonable doubt it is kept, the detector's planted ankle over it (0.07-0.17 m), else theirs is applied.
    plane = rows[0]
    if plane["ankle_plane_decision"] == "kept":
        assert totals["ankle_plane_over_floor_m"] == pytest.approx(plane["ankle_plane_m"] + 0.15)
        assert 0.07 <= plane["ankle_plane_m"] <= 0.17 and plane["ankle_plane_chance_off"] < APPLY_CHANCE
    else:
        assert 0.0 < totals["ankle_plane_over_floor_m"] < 0.25
    assert "0.15 m off the floor" in write(tmp_path, rows)[1].read_text()
