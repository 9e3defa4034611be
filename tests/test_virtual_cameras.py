"""Virtual camera sets: documented sizes, orbit geometry, the in-image filter, the random sampler."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d.data import virtual_cameras as vc


def test_grid_sizes_before_filtering():
    assert len(vc.grid("train")) == 3 * 19 * 6
    names = [c.name for c in vc.grid("extrinsic-test")]
    assert sum(n.startswith("rotation:") for n in names) == 12
    assert sum(n.startswith("distance:") for n in names) == 3 * 6
    # The pitch sweep's 15-degree cameras duplicate the rotation sweep's at yaws 30, 150, 270.
    assert sum(n.startswith("pitch:") for n in names) == 3 * 30 - 3
    assert len(vc.grid("intrinsic-test")) == 100
    assert len(vc.grid("scale-test")) == 12 and vc.SCALE_TEST_FACTORS == (0.6, 0.7, 0.8, 0.9, 1.1)
    assert len(vc.grid("h36m")) == 28
    assert len({c.name for c in vc.grid("train")}) == 342  # names are unique and stable


def test_orbit_cameras_look_at_the_target():
    for camera in vc.grid("extrinsic-test")[::10]:
        _, yaw, pitch, dist = camera.name.split(":")
        assert np.linalg.norm(camera.center - vc.ORBIT_TARGET) == pytest.approx(float(dist[4:]))
        assert np.degrees(camera.pitch) == pytest.approx(float(pitch[5:]))
        np.testing.assert_allclose(camera.project(vc.ORBIT_TARGET[None])[0], camera.intrinsics[2:], atol=1e-6)


def test_intrinsic_set_shares_extrinsics_and_spans_the_offsets():
    cams = vc.grid("intrinsic-test")
    assert all(np.allclose(c.R, cams[0].R) and np.allclose(c.t, cams[0].t) for c in cams)
    fx = sorted({round(c.intrinsics[0], 6) for c in cams})
    cx = sorted({round(c.intrinsics[2], 6) for c in cams})
    assert len(fx) == 10 and len(cx) == 10 and fx[-1] - fx[0] == pytest.approx(90.0)


def test_filter_keeps_only_cameras_that_see_every_joint(test_motion):
    clips = [vc.centre_clip(test_motion.clip(i)) for i in range(0, test_motion.num_clips, 6)]
    for set_name in ("extrinsic-test", "h36m"):
        kept = vc.camera_set(set_name, clips)
        assert 0 < len(kept) <= len(vc.grid(set_name))
        for camera in kept:
            pixels = camera.project(np.concatenate(clips).reshape(-1, 3))
            width, height = camera.image_size
            assert np.all((pixels >= 0) & (pixels <= [width - 1, height - 1]))
    # A clip high above the floor is seen by none of the (downward-looking) orbit cameras.
    far = [clips[0] + np.array([0.0, 0.0, 20.0])]  # 20 m up in the air: above every camera
    assert vc.camera_set("extrinsic-test", far) == []


def test_random_cameras_respect_their_ranges(rng):
    ranges = vc.CameraRanges(roll_deg=5.0, distortion_k1=(-0.2, -0.1))
    targets = rng.uniform([-3, -3, 0.8], [3, 3, 1.2], (500, 3))
    batch = vc.sample_cameras(targets, rng, ranges)
    assert np.all(batch.height >= ranges.min_height_m)
    assert np.all((np.degrees(batch.pitch) >= 0) & (np.degrees(batch.pitch) <= 45))
    cams = [batch.camera(i) for i in range(0, 500, 50)]
    for camera, height, pitch in zip(cams, batch.height[::50], batch.pitch[::50]):
        assert camera.camera_height == pytest.approx(height) and camera.pitch == pytest.approx(pitch)
        assert abs(np.degrees(camera.roll)) <= 5.0 + 1e-9
    pixels = np.stack([c.project(t[None])[0] for c, t in zip(cams, targets[::50])])
    assert np.all(np.abs(pixels - 500) < 400)  # the person is near the middle of the image
    assert np.all(batch.dist[:, 0] <= -0.1)


def test_mounted_cameras_hang_at_their_height_and_see_the_person(rng):
    ranges = vc.CameraRanges(height_m=(0.5, 12.0), distance_m=(2.0, 40.0), pitch_deg=(-5.0, 70.0), roll_deg=8.0,
                             hfov_deg=(15.0, 110.0), image_size=(1280, 720))
    targets = rng.uniform([-3, -3, 0.8], [3, 3, 1.2], (400, 3))
    batch = vc.sample_cameras(targets, rng, ranges)
    assert np.all((batch.height >= 0.5) & (batch.height <= 12.0))
    assert np.all((np.degrees(batch.pitch) >= -5 - 1e-9) & (np.degrees(batch.pitch) <= 70 + 1e-9))
    distance = np.linalg.norm(targets[:, :2] - np.stack([batch.camera(i).center[:2] for i in range(400)]), axis=1)
    assert distance.min() >= 2.0 - 1e-9 and distance.max() <= 40.0 + 1e-9 and np.median(distance) < 15
    hfov = np.degrees(2 * np.arctan(640 / batch.intrinsics[:, 0]))
    assert hfov.min() >= 15 - 1e-6 and hfov.max() <= 110 + 1e-6
    pixels = np.stack([batch.camera(i).project(targets[i]) for i in range(400)])
    assert np.all((pixels >= 0) & (pixels <= [1280, 720]))  # the person is in view, anywhere in the image
    assert np.std(pixels[:, 0]) > 150


def test_far_and_low_sets_are_where_their_names_say(mocap_dir):
    far, low = vc.grid("far-test"), vc.grid("low-test")
    assert len(far) == 60 and len(low) == 108 and len({c.name for c in far + low}) == 168
    for camera in far:
        distance = np.linalg.norm(camera.center[:2])
        assert 15 - 1e-9 <= distance <= 40 + 1e-9 and 3 - 1e-9 <= camera.camera_height <= 12 + 1e-9
        assert camera.sees(np.array([0.0, 0.0, 1.0]))
    for camera in low:
        assert 0.8 - 1e-9 <= camera.camera_height <= 2 + 1e-9 and -3 - 1e-9 <= np.degrees(camera.pitch) <= 8 + 1e-9


def test_the_near_set_is_near_low_and_wide():
    near = vc.grid("near-test")
    assert len(near) == 48 and len({c.name for c in near}) == 48
    for camera in near:
        assert 1.5 - 1e-9 <= np.linalg.norm(camera.center[:2]) <= 6 + 1e-9
        assert 0.8 - 1e-9 <= camera.camera_height <= 3 + 1e-9
        assert 2 * np.degrees(np.arctan(camera.image_size[0] / 2 / camera.K[0, 0])) == pytest.approx(90.0)
        assert camera.sees(np.array([[0.0, 0.0, 1.0]]))
