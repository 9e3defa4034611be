"""Training samples: window edges, the NCS identity, flips, bone scaling, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d.data.motion import MotionSet
from ray3d.data.samples import Batch, SampleConfig, SampleGenerator, flip_batch, observe, scale_bones
from ray3d.data.virtual_cameras import CameraRanges, grid
from ray3d.geometry import CameraBatch
from ray3d.geometry import transforms as tf
from ray3d.skeleton import H36M17
from ray3d.temporal import Window, sequence_windows, window_indices

NINE = Window(9)


def _motion(rng, lengths=(30, 3, 50)) -> MotionSet:
    clips = []
    for n in lengths:
        walk = np.cumsum(rng.normal(0, 0.01, (n, 1, 3)), axis=0) + np.array([0.0, 0.0, 0.0])
        pose = rng.normal(0, 0.2, (1, 17, 3)) + np.array([0.0, 0.0, 1.0])
        clips.append((pose + walk).astype(np.float32))
    return MotionSet.from_clips(clips, clip_id=[f"c{i}" for i in range(len(lengths))], subject="s")


def test_generator_windows_stay_inside_their_clip(rng):
    motion = _motion(rng)
    generator = SampleGenerator(motion, SampleConfig(), NINE, seed=1)
    centres = np.arange(motion.num_frames)
    idx = window_indices(centres, generator.first[centres], generator.last[centres], NINE)
    clip_of = np.searchsorted(motion.clip_start, idx, side="right") - 1
    assert np.all(clip_of == clip_of[:, 4:5])


def test_rays_and_targets_satisfy_the_ncs_identity(rng):
    config = SampleConfig(flip_probability=0.0, cameras=CameraRanges(distortion_k1=(-0.2, 0.0), roll_deg=4))
    batch = SampleGenerator(_motion(rng), config, NINE, seed=2).batch(64)
    assert batch.rays.shape == (64, 9, 17, 3) and batch.pixels.shape == (64, 9, 17, 2)
    assert (batch.pose.shape == (64, 17, 3) and batch.root.shape == (64, 3)
            and batch.cameras.height_pitch.shape == (64, 2))
    np.testing.assert_array_equal(batch.pose[:, 0], 0.0)
    cams = batch.cameras
    depth = tf.world_to_camera(batch.world.astype(np.float64), cams.R[:, None], cams.t[:, None])[..., 2:3]
    target = batch.pose + batch.root[:, None]
    expected = depth * batch.rays[:, 4] + np.stack([np.zeros(64), -cams.height, np.zeros(64)], -1)[:, None]
    np.testing.assert_allclose(target, expected, atol=1e-4)
    # The rays also come back from the pixels through the (distorted) lens.
    rays = tf.rays_camera_to_normalized(tf.pixels_to_camera_rays(batch.pixels.astype(np.float64),
                                                                 cams.intrinsics[:, None, None],
                                                                 cams.dist[:, None, None]), cams.pitch[:, None, None])
    np.testing.assert_allclose(rays, batch.rays, atol=1e-5)


def test_flip_twice_is_the_identity_and_flip_mirrors(rng):
    batch = SampleGenerator(_motion(rng), SampleConfig(flip_probability=0.0), NINE, seed=3).batch(16)
    mask = np.arange(16) % 2 == 0
    twice = flip_batch(flip_batch(batch, mask), mask)
    for field in ("pixels", "rays", "pose", "root", "visible"):
        np.testing.assert_allclose(getattr(twice, field), getattr(batch, field), atol=1e-4)
    once = flip_batch(batch, mask)
    np.testing.assert_array_equal(once.rays[mask][..., H36M17.index("l_wrist"), 0],
                                  -batch.rays[mask][..., H36M17.index("r_wrist"), 0])
    np.testing.assert_array_equal(once.rays[~mask], batch.rays[~mask])
    np.testing.assert_array_equal(once.cameras.height_pitch, batch.cameras.height_pitch)


def test_bone_scaling_keeps_directions_and_regrounds(rng):
    pose = rng.normal(0, 0.3, (4, 17, 3)) + np.array([0, 0, 1.0])
    np.testing.assert_allclose(scale_bones(pose, np.ones((4, 17))), pose, atol=1e-12)
    scaled = scale_bones(pose, np.full((4, 17), 0.8))
    for joint, parent in enumerate(H36M17.parents[1:], start=1):
        before, after = pose[:, joint] - pose[:, parent], scaled[:, joint] - scaled[:, parent]
        np.testing.assert_allclose(after, 0.8 * before, atol=1e-12)
    np.testing.assert_allclose(scaled[:, [3, 6], 2].min(-1), pose[:, [3, 6], 2].min(-1), atol=1e-12)


def test_noise_and_dropped_joints(rng):
    config = SampleConfig(noise_px=3.0, drop_probability=0.2, flip_probability=0.0)
    batch = SampleGenerator(_motion(rng), config, NINE, seed=4).batch(512)
    cams = batch.cameras
    clean = tf.camera_to_pixels(tf.world_to_camera(batch.world.astype(np.float64), cams.R[:, None], cams.t[:, None]),
                                cams.intrinsics[:, None])
    observed, visible = batch.pixels[:, 4], batch.visible[:, 4]
    assert 0.15 < 1 - batch.visible.mean() < 0.25 and batch.visible[..., 0].all()
    residual = observed - clean
    assert np.std(residual[visible]) == pytest.approx(3.0, rel=0.1)
    parents = np.array([max(p, 0) for p in H36M17.parents])
    to_parent = observed - clean[:, parents]
    assert np.std(to_parent[~visible]) == pytest.approx(3.0, rel=0.15)  # a dropped joint sits on its parent
    assert np.isfinite(batch.rays).all()


def test_same_seed_same_batches(rng):
    motion = _motion(rng)
    a, b = (SampleGenerator(motion, SampleConfig(noise_px=1.0), NINE, seed=7).batch(32) for _ in range(2))
    np.testing.assert_array_equal(a.rays, b.rays)
    np.testing.assert_array_equal(a.root, b.root)


def test_observe_without_rng_is_exact_for_fixed_cameras(rng):
    camera = grid("extrinsic-test")[0]
    clip = _motion(rng).clip(0).astype(np.float64)
    windows = sequence_windows(clip, NINE)
    cams = CameraBatch.from_cameras([camera] * len(windows))
    batch = observe(windows, cams, NINE)
    np.testing.assert_allclose(batch.root, camera.world_to_normalized(clip[:, 0]), atol=1e-5)
    np.testing.assert_allclose(batch.rays[:, 4], camera.pixels_to_rays(camera.project(clip)), atol=1e-6)
    assert isinstance(batch, Batch)


def test_gravity_aligned_samples_keep_the_ncs_identity(rng):
    config = SampleConfig(flip_probability=0.0, cameras=CameraRanges(roll_deg=6.0))
    batch = SampleGenerator(_motion(rng), config, NINE, remove_roll=True, seed=5).batch(64)
    cams = batch.cameras
    assert np.abs(cams.roll).max() > np.radians(1)
    depth = tf.world_to_camera(batch.world.astype(np.float64), cams.R[:, None], cams.t[:, None])[..., 2:3]
    expected = depth * batch.rays[:, 4] + np.stack([np.zeros(64), -cams.height, np.zeros(64)], -1)[:, None]
    np.testing.assert_allclose(batch.pose + batch.root[:, None], expected, atol=1e-4)
    world_up = np.array([0.0, 0.0, 1.0])
    up_in_ncs = tf.rays_camera_to_normalized((cams.R @ world_up), cams.pitch, cams.roll)
    np.testing.assert_allclose(up_in_ncs, np.tile([0.0, -1.0, 0.0], (64, 1)), atol=1e-9)


def test_causal_samples_target_the_window_end(rng):
    motion = _motion(rng)
    batch = SampleGenerator(motion, SampleConfig(flip_probability=0.0, bone_scale=(1, 1), bone_jitter=0.0),
                            Window(9, causal=True), seed=3).batch(32)
    cams = batch.cameras
    depth = tf.world_to_camera(batch.world.astype(np.float64), cams.R[:, None], cams.t[:, None])[..., 2:3]
    expected = depth * batch.rays[:, -1] + np.stack([np.zeros(32), -cams.height, np.zeros(32)], -1)[:, None]
    np.testing.assert_allclose(batch.pose + batch.root[:, None], expected, atol=1e-4)


def test_joint_offsets_are_mirrored_and_move_with_the_body(rng):
    from ray3d.data.detector_emulation import body_frames, offset_joints

    windows = rng.normal(0, 0.2, (4, 9, 17, 3)) + [0, 0, 1.0]
    offsets = rng.normal(0, 0.03, (4, 17, 3))
    moved = offset_joints(windows, body_frames(windows), offsets, H36M17)
    local = np.einsum("bfji,bfkj->bfki", body_frames(windows), moved - windows)  # back in the body frame
    np.testing.assert_allclose(local, np.broadcast_to(local[:, :1], local.shape), atol=1e-12)  # same every frame
    l_hip, r_hip, spine = (H36M17.index(n) for n in ("l_hip", "r_hip", "spine"))
    np.testing.assert_allclose(local[:, 0, l_hip], local[:, 0, r_hip] * [-1, 1, 1], atol=1e-12)
    np.testing.assert_allclose(local[:, 0, spine, 0], 0.0, atol=1e-12)  # central joints stay central


def test_detector_noise_grows_with_the_person_and_legs_swap(rng):
    from ray3d.data.samples import leg_swap

    config = SampleConfig(flip_probability=0.0, noise_height_fraction=(0.02, 0.02), swap_probability=1.0)
    batch = SampleGenerator(_motion(rng), config, NINE, seed=9).batch(256)
    cams = batch.cameras
    clean = tf.camera_to_pixels(tf.world_to_camera(batch.world.astype(np.float64), cams.R[:, None], cams.t[:, None]),
                                cams.intrinsics[:, None])[:, leg_swap(H36M17)]
    span = np.ptp(clean, axis=1).max(-1)
    residual = (batch.pixels[:, 4] - clean) / span[:, None, None]
    assert np.std(residual) == pytest.approx(0.02, rel=0.1)
    assert np.isfinite(batch.rays).all()


def _standing(count: int, frames: int = 9) -> np.ndarray:
    """(count, frames, 17, 3) an upright person (a fixed adult pose) at the world origin."""
    from ray3d.demo import demo_clip

    pose = demo_clip()[0].astype(np.float64)
    pose = pose - np.array([*pose[0, :2], 0.0])
    return np.broadcast_to(pose, (count, frames, 17, 3)).copy()


def _level_cameras(count: int, size=(1280, 720), distance=3.0, pitch_deg=0.0, height=1.2) -> CameraBatch:
    from ray3d.data.virtual_cameras import mounted_camera
    from ray3d.geometry import pinhole_intrinsics

    camera = mounted_camera(0.0, height, distance, pitch_deg, "level", pinhole_intrinsics(size, hfov_deg=60.0), size)
    return CameraBatch.repeated(camera, count)


def test_joints_outside_the_picture_are_unseen_and_stand_on_their_parents(rng):
    """A level camera 1.5 m from an adult in landscape cuts the feet: the ankles (and what is off the image) are
    unseen, stand where their nearest seen ancestor is, with confidence 0; the hips stay seen."""
    windows = _standing(2)
    cameras = _level_cameras(2, distance=1.5)
    batch = observe(windows, cameras, NINE, rng=rng, config=SampleConfig(hide_outside_image=True))
    clean = observe(windows, cameras, NINE)
    outside = ((clean.pixels[:, 4] < 0) | (clean.pixels[:, 4] > [1280, 720])).any(-1)
    ankle, knee, hip = (H36M17.index(n) for n in ("l_ankle", "l_knee", "l_hip"))
    assert outside[:, ankle].all()
    assert (~batch.visible[:, :, outside[0]]).all() and (batch.confidences[:, :, outside[0]] == 0).all()
    assert batch.visible[:, :, [0, hip, H36M17.index("r_hip")]].all()
    ancestor = knee if not outside[0, knee] else hip
    np.testing.assert_allclose(batch.pixels[:, :, ankle], batch.pixels[:, :, ancestor])
    np.testing.assert_allclose(batch.rays[:, :, ankle], batch.rays[:, :, ancestor])
    np.testing.assert_allclose(batch.pose, clean.pose)  # the targets are the whole person


def test_an_occluder_hides_what_is_below_its_row_and_never_the_hips(rng):
    from ray3d.data.detector_emulation import hidden_joints, occluder_rows

    pixels = observe(_standing(64), _level_cameras(64, distance=4.0), NINE).pixels[:, 4]
    rows = occluder_rows(pixels, rng, 0.5, H36M17)
    occluded = np.isfinite(rows)
    assert 0.3 < occluded.mean() < 0.7
    hidden = hidden_joints(pixels, np.full((64, 2), np.inf), rows, H36M17)
    below = pixels[..., 1] > np.nan_to_num(rows, nan=np.inf)[:, None]
    hips = [H36M17.index(n) for n in ("pelvis", "l_hip", "r_hip")]
    below[:, hips] = False
    np.testing.assert_array_equal(hidden, below)
    assert not hidden[~occluded].any() and hidden[occluded][:, H36M17.index("l_ankle")].all()


def test_detector_offsets_move_the_seen_joints_not_the_targets(rng):
    """The measured offsets at full scale lift an upright person's seen hips 0.065 m and ankles 0.05 m (their
    rays pass there); the targets stay the mocap's joints."""
    from ray3d.body import DETECTOR_JOINT_OFFSETS_M

    windows, cameras = _standing(4), _level_cameras(4, distance=4.0)
    moved = observe(windows, cameras, NINE, rng=rng, config=SampleConfig(detector_offset_scale=(1.0, 1.0)))
    clean = observe(windows, cameras, NINE)
    np.testing.assert_allclose(moved.pose, clean.pose)
    depth = tf.world_to_camera(windows[:, 4], cameras.R[:, None], cameras.t[:, None])[..., 2]
    camera = cameras.camera(0)
    for name, (_, _, up) in DETECTOR_JOINT_OFFSETS_M.items():
        j = H36M17.index(f"l_{name}")
        rays = tf.rays_normalized_to_camera(moved.rays[:, 4, j].astype(np.float64), cameras.pitch)
        seen = camera.camera_to_world(rays * depth[:, j, None])
        assert np.median(seen[:, 2] - windows[:, 4, j, 2]) == pytest.approx(up, abs=0.01)


def test_seen_as_a_detector_derives_the_h36m_joints_as_lifting_does(rng):
    """Seen as COCO-17, the model's thorax is the mid-shoulders and its head comes from the ears, exactly as
    ``ray3d.skeleton.convert_keypoints`` makes them from a detector's keypoints."""
    from ray3d.data.detector_emulation import detector_points
    from ray3d.skeleton import convert_keypoints

    windows, cameras = _standing(3), _level_cameras(3, distance=4.0)
    batch = observe(windows, cameras, NINE, config=SampleConfig(seen_as="coco17"))
    coco = cameras.camera(0).project(detector_points(windows[0, 4], "coco17"))
    expected, _ = convert_keypoints(coco, "coco17")
    np.testing.assert_allclose(batch.pixels[0, 4], expected, atol=1e-6)


def test_portrait_cameras_and_camera_mixtures(rng):
    """A portrait share turns images on their side (principal point near the portrait centre, the person in
    view); extra camera ranges take their shares of a batch."""
    motion = _motion(rng, (60,))
    near = CameraRanges(height_m=(0.8, 1.5), distance_m=(2.0, 5.0), pitch_deg=(0.0, 15.0), hfov_deg=(50.0, 80.0),
                        image_size=(1280, 720), portrait_probability=1.0)
    config = SampleConfig(flip_probability=0.0, cameras=CameraRanges(image_size=(1280, 720)),
                          extra_cameras=(near,), extra_camera_shares=(0.5,))
    batch = SampleGenerator(motion, config, NINE, seed=3).batch(400)
    sizes = batch.cameras.sizes
    portrait = sizes[:, 1] > sizes[:, 0]
    assert 0.4 < portrait.mean() < 0.6
    np.testing.assert_allclose(batch.cameras.height[portrait], np.clip(batch.cameras.height[portrait], 0.8, 1.5))
    assert np.all(np.abs(batch.cameras.intrinsics[portrait, 2:] - [360, 640]) <= 60)
    pelvis = batch.pixels[:, 4, 0]
    assert np.mean(((pelvis >= 0) & (pelvis <= sizes)).all(-1)) > 0.95
    with pytest.raises(Exception, match="extra_camera_shares"):
        SampleConfig(extra_cameras=(near,), extra_camera_shares=())


def test_a_child_share_shrinks_the_body_and_the_head_less(rng):
    from ray3d.data.samples import child_factors

    factors = child_factors(2000, rng, SampleConfig(child_probability=0.25, child_scale=(0.6, 0.8)))
    child = factors[:, 1] < 1
    assert 0.2 < child.mean() < 0.3 and (factors[~child] == 1).all()
    head = H36M17.index("head")
    assert (factors[child, head] > factors[child, 1]).all() and (factors[child, 1] >= 0.6).all()
