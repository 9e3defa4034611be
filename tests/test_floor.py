"""Floors that are not flat: the floor test of the refinement (a person on an undeclared platform is not pushed
into the ground), declared floor regions (a person on a stage rests on it), the floor file, and the reported
uncertainty against errors of known size."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import Camera, InputError
from ray3d.body import body_sizes
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.geometry.floor import FLAT_FLOOR, Floor, FloorRegion
from ray3d.io.camera_files import floor_of_camera_file, read_floor, save_cameras
from ray3d.metrics import root_error_in_sds
from ray3d.refine import RefineConfig, refine_track, scale_about
from ray3d.skeleton import H36M17

ANKLES = [H36M17.index("l_ankle"), H36M17.index("r_ankle")]
CONFIG = RefineConfig(keypoint_error=0.0)
STAGE = Floor((FloorRegion("stage", np.array([[-3.0, -3.0], [3.0, -3.0], [3.0, 3.0], [-3.0, 3.0]]), 0.3),))


def _near_camera() -> Camera:
    """1.6 m up, 5 m from the origin, looking at it (Human3.6M's cameras): where the network's distance is good to
    a few per cent and a 0.3 m platform changes the distance at which the feet rest on the floor by 25 %."""
    camera = Camera.from_height_pitch(1.6, 8.0, (1280, 720), hfov_deg=60.0)
    return Camera(camera.K, camera.dist, camera.R, camera.t + camera.R @ [5.0, 0.0, 0.0], camera.image_size)


def _person(raised: float = 0.0, frames: int = 90) -> np.ndarray:
    """A walking person of the prior's size, lowest ankle at the contact height above a floor ``raised`` m up."""
    clip = demo_clip()[:frames].astype(np.float64)
    clip = clip * (CONFIG.body_size_m / body_sizes(clip))[:, None, None]
    clip[..., :2] -= clip[:, :1, :2].mean(axis=0)
    clip[..., 2] += CONFIG.contact_ankle_height_m + raised - clip[:, ANKLES, 2].min(1)[:, None]
    return clip


def _rays(camera: Camera, points: np.ndarray) -> np.ndarray:
    return camera.pixels_to_camera_rays(camera.project(points)) @ camera.R


def test_the_floor_test_flags_a_person_on_a_platform_and_not_one_on_the_floor():
    camera = _near_camera()
    for raised, expected in ((0.0, True), (0.3, False)):
        truth = _person(raised)
        refined, found = refine_track(truth, camera, 60.0, _rays(camera, truth), config=CONFIG)
        assert found.floor_cue.all() == expected and found.floor_cue.any() == expected
        # Where the floor is not used, its height is estimated from the network's distances (here exact).
        np.testing.assert_allclose(found.floor_height_m, raised, atol=0.02)
        assert np.abs(refined - truth).max() < 0.04
    # Without the test, the floor term would push the raised person 1.4 m down their rays.
    truth = _person(0.3)
    blind, _ = refine_track(truth, camera, 60.0, _rays(camera, truth),
                            config=RefineConfig(keypoint_error=0.0, agreement_sigmas=np.inf))
    assert np.abs(blind[:, 0] - truth[:, 0]).max() > 0.3


def test_a_person_on_a_declared_stage_rests_on_it():
    """The network puts the person 10 % too far: on the plain floor that is consistent with a floor 0.3 m lower,
    so the test drops the floor; with the stage declared, the stage pulls the person back onto it."""
    camera, truth = _near_camera(), _person(0.3)
    too_far = scale_about(truth, camera.center, np.full(len(truth), 1.1))
    plain, unsure = refine_track(too_far, camera, 60.0, _rays(camera, truth), config=CONFIG)
    staged, found = refine_track(too_far, camera, 60.0, _rays(camera, truth), config=CONFIG, floor=STAGE)
    assert found.floor_cue.all() and found.contact.mean() > 0.9
    np.testing.assert_allclose(found.floor_height_m, 0.3, atol=1e-9)
    lowest = staged[:, ANKLES, 2].min(1)
    assert np.median(lowest) == pytest.approx(0.3 + CONFIG.contact_ankle_height_m, abs=0.05)

    def error(joints):
        return np.linalg.norm(joints[:, 0] - truth[:, 0], axis=-1).mean()

    assert error(staged) < 0.3 * error(plain) and error(plain) > 0.7 * error(too_far)


def test_a_ramp_is_a_plane_through_its_vertices_and_the_first_region_decides():
    ramp = FloorRegion.from_vertex_heights("ramp", [[0, 0], [4, 0], [4, 2], [0, 2]], [0.0, 0.4, 0.4, 0.0])
    floor = Floor((STAGE.regions[0], ramp))
    assert ramp.gradient == pytest.approx((0.1, 0.0)) and ramp.plane_height(np.array([2.0, 1.0])) == pytest.approx(0.2)
    heights, gradients = floor.height_and_gradient(np.array([[3.5, 1.0], [0.0, 0.0], [10.0, 10.0]]))
    # (3.5, 1) is on the ramp only; (0, 0) is on both and the stage, listed first, decides; (10, 10) is floor.
    np.testing.assert_allclose(heights, [0.35, 0.3, 0.0])
    np.testing.assert_allclose(gradients, [[0.1, 0.0], [0.0, 0.0], [0.0, 0.0]], atol=1e-12)
    assert FLAT_FLOOR.height(np.zeros((4, 5, 2))).shape == (4, 5)


def test_a_person_walking_up_a_declared_ramp_is_placed_on_it():
    ramp = Floor((FloorRegion.from_vertex_heights("ramp", [[-5, -5], [5, -5], [5, 5], [-5, 5]],
                                                  [0.0, 1.0, 1.0, 0.0]),))
    camera, truth = _near_camera(), _person()
    truth[..., 2] += ramp.height(truth[:, :1, :2])  # each frame lifted by the ramp under the person
    too_close = scale_about(truth, camera.center, np.full(len(truth), 0.95))
    refined, found = refine_track(too_close, camera, 60.0, _rays(camera, truth), config=CONFIG, floor=ramp)
    flat, _ = refine_track(too_close, camera, 60.0, _rays(camera, truth), config=CONFIG)
    assert found.floor_cue.mean() > 0.9

    def error(joints):
        return np.linalg.norm(joints[:, 0] - truth[:, 0], axis=-1).mean()

    assert error(refined) < 0.35 * error(too_close) and error(refined) < 0.5 * error(flat)


def test_the_root_error_in_sds_of_known_errors():
    camera = _near_camera()
    truth = _person(frames=3)
    ray = truth[:, 0] - camera.center
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    side = np.cross(ray, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side, axis=-1, keepdims=True)
    predicted = truth.copy()
    predicted[:, 0] += np.array([0.2, -0.05, 0.0])[:, None] * ray + np.array([0.0, 0.0, 0.03])[:, None] * side
    sds = np.array([[0.1, 0.01], [0.1, 0.01], [0.1, 0.01]])
    # Along: 2 sd, 0.5 sd and none; across, in the floor plane: none, none and 3 sd (up to the small turn of the
    # ray through the displaced root, from which the axes are taken).
    np.testing.assert_allclose(root_error_in_sds(predicted, truth, sds, camera), [[2.0, 0.0], [0.5, 0.0], [0.0, 3.0]],
                               atol=0.02)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.02, 0.5), st.integers(0, 2**16))
def test_gaussian_errors_of_the_stated_size_are_covered_as_a_gaussian_is(sd, seed):
    """Errors drawn with the stated sd along the ray: about 68 % within 1 sd and 95 % within 2."""
    rng = np.random.default_rng(seed)
    camera, truth = _near_camera(), np.repeat(_person(frames=1), 4000, axis=0)
    ray = truth[:, 0] - camera.center
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    predicted = truth + (rng.normal(0, sd, len(truth))[:, None] * ray)[:, None]
    in_sds = root_error_in_sds(predicted, truth, np.tile([sd, 1.0], (len(truth), 1)), camera)[:, 0]
    assert 0.65 < np.mean(in_sds <= 1) < 0.71 and 0.93 < np.mean(in_sds <= 2) < 0.97


def test_the_uncertainty_grows_with_the_distance_and_shrinks_with_the_floor():
    camera, truth = _near_camera(), _person()
    _, seen = refine_track(truth, camera, 60.0, _rays(camera, truth), config=CONFIG)
    _, hidden = refine_track(truth, camera, 60.0, _rays(camera, truth), config=CONFIG,
                             feet_seen=np.zeros(len(truth), bool))
    along_seen, along_hidden = np.median(seen.position_sd_m[:, 0]), np.median(hidden.position_sd_m[:, 0])
    assert 0.0 < along_seen < along_hidden < 0.5
    assert hidden.stature_sd_m > 0 and seen.summary()["stature_interval_m"][0] < seen.stature_m


def _floor_file(tmp_path, regions, name="floor.json"):
    path = tmp_path / name
    path.write_text(json.dumps({"floor_regions": regions}))
    return path


def test_a_floor_file_reads_flat_and_sloped_regions(tmp_path):
    path = _floor_file(tmp_path, [{"name": "stage", "polygon": [[0, 0], [2, 0], [2, 2], [0, 2]], "height_m": 0.5},
                                  {"polygon": [[3, 0], [5, 0], [5, 1], [3, 1]], "vertex_heights_m": [0, 0.2, 0.2, 0]}])
    floor = read_floor(path)
    np.testing.assert_allclose(floor.height(np.array([[1.0, 1.0], [4.0, 0.5], [9.0, 9.0]])), [0.5, 0.1, 0.0])
    assert floor.regions[1].name == "region 1"
    again = _floor_file(tmp_path, floor.to_dict()["regions"], "again.json")
    np.testing.assert_allclose(read_floor(again).height(np.array([[4.5, 0.2]])), floor.height(np.array([[4.5, 0.2]])))


@pytest.mark.parametrize("regions, message", [
    ("stage", "expected a list of regions"),
    ([], "expected a list of regions"),
    ([3], r"floor_regions\[0\]: expected an object"),
    ([{"polygon": [[0, 0], [1, 0]], "height_m": 0.2}], r"floor_regions\[0\].polygon: expected 3 or more"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]]}], "exactly one of height_m"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]], "height_m": 0.2, "vertex_heights_m": [0, 0, 0]}], "exactly one of"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]], "height_m": [0.2, 0.3]}], "height_m: expected one number"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]], "vertex_heights_m": [0, 0, 0.5, 0]}], "off one plane"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]], "vertex_heights_m": [0, 0]}], "2 vertex heights for 3 vertices"),
    ([{"polygon": [[0, 0], [1, 0], [2, 0]], "height_m": 0.2}], "encloses no area"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]], "vertex_heights_m": [0, 2, 2]}], "steeper than 45 deg"),
    ([{"polygon": [[0, 0], [1, 0], [1, "x"]], "height_m": 0.2}], "not numeric"),
    ([{"polygon": [[0, 0], [1, 0], [1, 1]], "height": 0.2}], "unknown field 'height'"),
])
def test_bad_floor_regions_are_refused_naming_the_file_and_field(tmp_path, regions, message):
    path = _floor_file(tmp_path, regions)
    with pytest.raises(InputError, match=message) as caught:
        read_floor(path)
    assert str(path) in caught.value.message


def test_a_camera_file_may_carry_its_floor(tmp_path):
    from ray3d import cameras

    path = tmp_path / "camera.json"
    document = cameras.h36m("S9", "55011271").to_dict()
    path.write_text(json.dumps(document))
    assert floor_of_camera_file(path) == FLAT_FLOOR and floor_of_camera_file(None) == FLAT_FLOOR
    path.write_text(json.dumps({**document, "floor_regions": [{"polygon": [[0, 0], [1, 0], [1, 1]], "height_m": 0.4}]}))
    assert floor_of_camera_file(path).height(np.array([0.8, 0.2])) == pytest.approx(0.4)
    save_cameras(tmp_path / "list.json", [cameras.h36m("S9", "55011271")])
    assert floor_of_camera_file(tmp_path / "list.json") == FLAT_FLOOR


def test_a_bad_floor_file_on_the_command_line_is_one_line_and_exit_2(tmp_path, tiny_checkpoint, capsys):
    from ray3d import cameras

    camera = cameras.h36m("S9", "55011271")
    pixels = camera.project(_person(frames=12))
    keypoints = tmp_path / "k.npz"
    np.savez(keypoints, keypoints=pixels, layout="h36m17", fps=30.0)
    floor = _floor_file(tmp_path, [{"polygon": [[0, 0], [1, 0]], "height_m": 0.2}])
    code = main(["lift", "--keypoints", str(keypoints), "--camera", "h36m:S9:55011271", "--floor", str(floor),
                 "--out", str(tmp_path / "o.json"), "--checkpoint", str(tiny_checkpoint)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "polygon" in err and str(floor) in err
    good = _floor_file(tmp_path, [{"polygon": [[-9, -9], [9, -9], [9, 9], [-9, 9]], "height_m": 0.0}], "good.json")
    assert main(["lift", "--keypoints", str(keypoints), "--camera", "h36m:S9:55011271", "--floor", str(good),
                 "--out", str(tmp_path / "o.json"), "--checkpoint", str(tiny_checkpoint)]) == 0
    capsys.readouterr()
    lifted = json.loads((tmp_path / "o.json").read_text())["tracks"]
    track = next(iter(lifted.values()))
    assert len(track["position_sd_m"]) == 12 and len(track["refinement"]["frames"]["floor_cue"]) == 12


def test_a_model_states_its_own_distance_error_and_the_rest_stays_the_defaults():
    from ray3d.checkpoints import load_model

    document = {"uncertainty": {"depth_bias_sd": [[0, 0.05], [60, 0.05]], "residual_distance_sd": 0.003,
                                "measured": "when and how"}}
    config = RefineConfig.for_model(document, keypoint_error=0.0)
    assert config.network_bias_sd(np.array([3.0, 30.0])) == pytest.approx([0.05, 0.05])
    assert config.residual_distance_sd == 0.003 and config.keypoint_error == 0.0
    assert config.floor_offset_sd_m == RefineConfig().floor_offset_sd_m
    assert RefineConfig.for_model({}) == RefineConfig()
    # The shipped detector model measured its own; the shipped ray3d's are the defaults.
    assert RefineConfig.for_model(load_model("ray3d-real")[1]).network_bias_sd(30.0) == pytest.approx(0.0396, abs=1e-4)
    assert RefineConfig.for_model(load_model("ray3d")[1]) == RefineConfig()


def test_a_foot_feels_a_plane_exactly_and_a_step_over_its_length():
    ramp = Floor((FloorRegion.from_vertex_heights("ramp", [[0, -5], [10, -5], [10, 5], [0, 5]], [0, 1, 1, 0]),))
    height, gradient = ramp.under_foot(np.array([[5.0, 0.0]]))
    np.testing.assert_allclose(height, [0.5]) and np.testing.assert_allclose(gradient, [[0.1, 0.0]], atol=1e-12)
    step = Floor((FloorRegion("step", np.array([[0.0, -5.0], [5.0, -5.0], [5.0, 5.0], [0.0, 5.0]]), 0.2),))
    at = np.array([[-1.0, 0.0], [0.0 + 1e-6, 0.0], [1.0, 0.0]])  # before the step, on its edge, on it
    height, gradient = step.under_foot(at)
    np.testing.assert_allclose(height, [0.0, 0.15, 0.2], atol=1e-9)  # three of the four samples are up at the edge
    assert gradient[1, 0] == pytest.approx(0.2 / 0.25) and gradient[0, 0] == gradient[2, 0] == 0.0
    assert FLAT_FLOOR.under_foot(at)[0].tolist() == [0.0, 0.0, 0.0]
