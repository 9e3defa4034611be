"""Track-level refinement: joints stay on their rays, the truth is a fixed point, a wrong distance is pulled
back by the floor, bad input is refused, and lifting far away gets the feet on the floor."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import Camera, InputError, Lifter, metrics
from ray3d.body import body_sizes
from ray3d.demo import demo_clip
from ray3d.refine import RefineConfig, refine_track, scale_about
from ray3d.skeleton import H36M17

ANKLES = [H36M17.index("l_ankle"), H36M17.index("r_ankle")]
CONFIG = RefineConfig()
EXACT_2D = RefineConfig(keypoint_error=0.0)


def _camera(height=7.0, pitch=16.0, distance=20.0) -> Camera:
    camera = Camera.from_height_pitch(height, pitch, (1280, 720), hfov_deg=50.0)
    return Camera(camera.K, camera.dist, camera.R, camera.t + camera.R @ [distance, 0.0, 0.0], camera.image_size)


def _consistent_person(frames=90, still=False) -> np.ndarray:
    """A real motion made to agree with the refinement's model: its size chain is the prior's and its lowest
    ankle stands at the contact height in every frame (``still``: the first pose held, at one distance)."""
    clip = demo_clip()[:frames]
    if still:
        clip = np.repeat(clip[:1], frames, axis=0)
    clip = clip * (CONFIG.body_size_m / body_sizes(clip))[:, None, None]
    clip[..., 2] += CONFIG.contact_ankle_height_m - clip[:, ANKLES, 2].min(1)[:, None]
    return clip


def _rays(camera: Camera, points: np.ndarray) -> np.ndarray:
    return camera.pixels_to_camera_rays(camera.project(points)) @ camera.R


def test_the_truth_is_a_fixed_point():
    camera, truth = _camera(), _consistent_person(still=True)
    for rays in (None, _rays(camera, truth)):
        refined, found = refine_track(truth, camera, 60.0, rays)
        np.testing.assert_allclose(refined, truth, atol=1e-6)
        np.testing.assert_allclose(found.scale, 1.0, atol=1e-6)
        assert found.contact.all() and found.body_size_m == pytest.approx(CONFIG.body_size_m, rel=1e-6)


def test_a_moving_truth_stays_within_centimetres():
    """Jumping and balancing changes the distance faster than the smoothness prior expects: it pulls a little."""
    camera, truth = _camera(), _consistent_person()
    refined, found = refine_track(truth, camera, 60.0, _rays(camera, truth))
    assert np.abs(refined - truth).max() < 0.02 and np.abs(found.scale - 1).max() < 1e-3


def _off_ray(points: np.ndarray, camera: Camera, rays: np.ndarray) -> np.ndarray:
    """(T, J) distances of points from the rays through the camera centre."""
    directions = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    offsets = points - camera.center
    return np.linalg.norm(offsets - np.einsum("tjk,tjk->tj", offsets, directions)[..., None] * directions, axis=-1)


@settings(max_examples=25, deadline=None)
@given(st.floats(0.5, 1.6), st.floats(-0.3, 0.3), st.booleans())
def test_the_person_stays_on_their_rays(scale, wobble, with_rays):
    """Given the observed rays of exact 2D, every joint ends on its ray; without them, every joint stays on the
    line from the camera through where the network put it."""
    camera, truth = _camera(), _consistent_person(40)
    factors = scale * (1 + wobble * np.sin(np.linspace(0, 3, len(truth))))
    wrong = scale_about(truth, camera.center, factors) + np.random.default_rng(0).normal(0, 0.02, truth.shape)
    rays = _rays(camera, truth) if with_rays else wrong - camera.center
    refined, _ = refine_track(wrong, camera, 30.0, rays if with_rays else None, config=EXACT_2D)
    np.testing.assert_allclose(_off_ray(refined, camera, rays), 0.0, atol=1e-9)


def test_a_detectors_joints_move_part_way_towards_their_rays_and_unmeasured_ones_keep_the_shape():
    """With a detector's keypoint error the root ends on its ray and each measured joint between the network's
    shape (what keypoints trusted not at all give, at one size for the track) and its ray; a joint without a
    ray (NaN) keeps the shape."""
    camera, truth = _camera(), _consistent_person(40)
    wrong = scale_about(truth, camera.center, np.full(len(truth), 0.9))
    wrong = wrong + np.random.default_rng(1).normal(0, 0.03, truth.shape)
    rays = _rays(camera, truth)
    rays[:, H36M17.index("head")] = np.nan
    shape_only, _ = refine_track(wrong, camera, 30.0, rays, config=RefineConfig(keypoint_error=1e9))
    refined, _ = refine_track(wrong, camera, 30.0, rays)
    ratio = body_sizes(shape_only) / body_sizes(wrong)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    np.testing.assert_allclose(refined[:, [0, H36M17.index("head")]], shape_only[:, [0, H36M17.index("head")]],
                               atol=1e-9)
    measured = [j for j in range(1, 17) if j != H36M17.index("head")]
    before, after = (_off_ray(points, camera, rays)[:, measured] for points in (shape_only, refined))
    assert (after < before).all() and (after > 0.1 * before).all()


def test_a_high_camera_pulls_a_person_placed_too_close_back_to_the_floor():
    camera, truth = _camera(height=7.0, distance=25.0), _consistent_person()
    wrong = scale_about(truth, camera.center, np.full(len(truth), 0.6))
    refined, found = refine_track(wrong, camera, 60.0, _rays(camera, truth))
    assert metrics.mrpe(wrong, truth) > 8.0 and metrics.mrpe(refined, truth) < 0.05 * metrics.mrpe(wrong, truth)
    assert np.median(found.scale) == pytest.approx(1 / 0.6, rel=0.03) and np.median(found.position_sd_m[:, 0]) < 0.5


def test_a_camera_at_ankle_height_learns_nothing_from_the_floor():
    camera, truth = _camera(height=0.1, pitch=-2.0, distance=8.0), _consistent_person(40)
    wrong = scale_about(truth, camera.center, np.full(len(truth), 0.8))
    _, found = refine_track(wrong, camera, 30.0)
    assert not found.contact.any()  # the feet are not below the camera: no floor term


@pytest.mark.parametrize("joints, fps, message", [
    (np.zeros((5, 16, 3)), 30.0, "expected finite"), (np.full((5, 17, 3), np.nan), 30.0, "expected finite"),
    (np.zeros((5, 17, 3)), 0.0, "fps must be positive"),
])
def test_bad_input_is_refused(joints, fps, message):
    with pytest.raises(InputError, match=message):
        refine_track(joints, _camera(), fps)


def test_lifting_far_away_puts_the_feet_on_the_floor():
    """End to end with the shipped model: a test performer 25 m from a camera 6 m up, beyond the distances the
    model was trained on; the network alone puts them metres too close and in the air."""
    camera, truth = _camera(height=6.0, pitch=12.0, distance=25.0), demo_clip()[:120]
    pixels = camera.project(truth)
    lifter = Lifter.load()
    network, refined = (lifter.lift(pixels, camera, refine=r) for r in (False, True))
    lowest = refined.joints[:, ANKLES, 2].min(1)
    assert metrics.mrpe(network.joints, truth) > 3.0 and metrics.mrpe(refined.joints, truth) < 0.6
    assert np.median(lowest) == pytest.approx(0.07, abs=0.1) and refined.refinement["stature_m"] > 1.5


def test_stature_reads_the_head_over_the_lower_ankle_as_a_share_of_height():
    from ray3d import body

    standing = np.zeros((4, 17, 3))
    standing[:, H36M17.index("l_ankle"), 2] = body.AXIS_HEIGHTS["ankles"] * 1.8
    standing[:, H36M17.index("r_ankle"), 2] = 0.3  # a foot lifted: the lower ankle counts
    standing[:, H36M17.index("head"), 2] = body.AXIS_HEIGHTS["head"] * 1.8
    assert body.stature(standing) == pytest.approx(1.8)
    crouched = standing.copy()
    crouched[:2, H36M17.index("head"), 2] = 1.0
    assert body.stature(crouched, upright=[False, False, True, True]) == pytest.approx(1.8)
    assert np.isnan(body.stature(standing[:0]))


def test_the_floor_cue_is_not_used_where_the_feet_are_not_seen():
    """A network's depth 10 % too far, 7 m from the camera (within what the floor test allows there): with the
    feet seen, the floor pulls the person back onto it; with the legs hidden (or out of the image) the floor is
    not used, and the upright head's ray, at the height a head of the person's size stands, pulls them back
    instead; with the head unseen as well only the network and the size are left, and the network's depth stands."""
    camera, truth = _camera(height=4.0, pitch=30.0, distance=6.0), _consistent_person(still=True)
    too_far = scale_about(truth, camera.center, np.full(len(truth), 1.1))
    rays = _rays(camera, truth)
    _, seen = refine_track(too_far, camera, 60.0, rays)
    _, hidden = refine_track(too_far, camera, 60.0, rays, feet_seen=np.zeros(len(truth), bool))
    headless = rays.copy()
    headless[:, H36M17.index("head")] = np.nan
    _, neither = refine_track(too_far, camera, 60.0, headless, feet_seen=np.zeros(len(truth), bool))
    assert seen.floor_cue.all() and seen.contact.mean() > 0.9 and abs(np.median(seen.scale) - 1 / 1.1) < 0.03
    assert not hidden.floor_cue.any() and not hidden.contact.any() and abs(np.median(hidden.scale) - 1 / 1.1) < 0.03
    assert not neither.floor_cue.any() and abs(np.median(neither.scale) - 1) < 0.03


def test_the_cues_that_carried_each_frame_are_reported():
    """Feet seen from a camera looking down: the floor carries the distance; legs hidden: the upright head; legs
    and head hidden: the network; the shares of every frame sum to one and the world file's record names a cue
    per frame."""
    from ray3d.refine import CUES

    camera, truth = _camera(height=4.0, pitch=30.0, distance=6.0), _consistent_person(still=True)
    too_far = scale_about(truth, camera.center, np.full(len(truth), 1.1))
    rays, legless = _rays(camera, truth), np.zeros(len(truth), bool)
    headless = rays.copy()
    headless[:, H36M17.index("head")] = np.nan
    _, seen = refine_track(too_far, camera, 60.0, rays)
    _, hidden = refine_track(too_far, camera, 60.0, rays, feet_seen=legless)
    _, neither = refine_track(too_far, camera, 60.0, headless, feet_seen=legless)
    for found in (seen, hidden, neither):
        np.testing.assert_allclose(found.cue_shares.sum(axis=1), 1.0)
    assert (seen.cue_shares.argmax(axis=1) == CUES.index("floor")).all()
    assert hidden.cue_shares[:, CUES.index("floor")].max() == 0.0
    assert (hidden.cue_shares.argmax(axis=1) == CUES.index("head")).all()
    assert neither.cue_shares[:, [CUES.index("floor"), CUES.index("head")]].max() == 0.0
    assert (neither.cue_shares.argmax(axis=1) == CUES.index("network")).all()
    record = seen.summary()
    assert record["frames"]["cue"] == ["floor"] * len(truth) and record["cue_shares"]["floor"] > 0.5


@settings(max_examples=20, deadline=None)
@given(st.floats(1.0, 7.0), st.floats(-3.0, 3.0), st.floats(6.0, 12.0), st.floats(0.85, 1.2))
def test_planted_feet_seen_never_leave_the_answer_worse_than_the_network(height, aim, distance, network_scale):
    """Noise-free: a person standing on the floor with the feet seen, the network's distance off by a shared
    factor; the foot's ray meeting the floor is exact, so the fused position is never worse than the network's
    (the better cue) and, where the ray meets the floor steeply enough to measure, much better."""
    pitch = np.degrees(np.arctan2(height - 1.0, distance)) + aim  # looking at the person, give or take
    camera, truth = _camera(height=height, pitch=pitch, distance=distance), _consistent_person(40, still=True)
    assert camera.sees(truth)
    wrong = scale_about(truth, camera.center, np.full(len(truth), network_scale))
    refined, found = refine_track(wrong, camera, 30.0, _rays(camera, truth), config=EXACT_2D)
    before, after = metrics.mrpe(wrong, truth), metrics.mrpe(refined, truth)
    assert after <= before + 1e-6
    if found.floor_cue.all() and abs(network_scale - 1) > 0.05:
        assert after < 0.5 * before


def test_a_detectors_ankle_stands_higher_than_the_mocaps():
    """Rays of a detector's keypoints pass through its ankle keypoint, which stands higher on a planted foot than
    the mocap's ankle joint: the refinement expects it there for detector layouts only."""
    from ray3d import body

    assert RefineConfig.for_model({}, "coco17").contact_ankle_height_m == body.DETECTOR_PLANTED_ANKLE_HEIGHT_M
    assert RefineConfig.for_model({}, "blazepose33").contact_ankle_height_m == body.DETECTOR_PLANTED_ANKLE_HEIGHT_M
    assert RefineConfig.for_model({}, "h36m17").contact_ankle_height_m == body.PLANTED_ANKLE_HEIGHT_M
    assert body.DETECTOR_PLANTED_ANKLE_HEIGHT_M > body.PLANTED_ANKLE_HEIGHT_M
    assert RefineConfig.for_model({}, "coco17", contact_ankle_height_m=0.1).contact_ankle_height_m == 0.1
    # Each detector's ankle rays meet a planted foot at its own height, which the floor's evidence is read against.
    assert RefineConfig.for_model({}, "blazepose33").keypoint_ankle_height_m == body.KEYPOINT_SOURCES[
        "blazepose33"].planted_ankle_m == 0.149
    assert RefineConfig.for_model({}, "h36m17").keypoint_ankle_height_m == body.PLANTED_ANKLE_HEIGHT_M
    assert RefineConfig.for_model({}, "body25").keypoint_ankle_height_m < body.DETECTOR_PLANTED_ANKLE_HEIGHT_M


def test_frames_the_network_put_at_the_camera_follow_their_neighbours():
    """A network that put the person at the camera in a few frames (seen on level-test) breaks nothing: those
    frames take the track's distances and the answer stays where the other frames put it."""
    camera, truth = _camera(), _consistent_person(40)
    broken = truth.copy()
    broken[10:13] = camera.center
    refined, found = refine_track(broken, camera, 30.0, _rays(camera, truth), config=EXACT_2D)
    assert np.isfinite(refined).all() and metrics.mrpe(refined, truth) < 0.1
    with pytest.raises(InputError, match="at the camera in every frame"):
        refine_track(np.broadcast_to(camera.center, truth.shape).copy(), camera, 30.0, _rays(camera, truth))
