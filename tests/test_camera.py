"""Camera model: frame round trips, the NCS identities, Human3.6M values, lens model vs OpenCV, bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import torch
from conftest import points_in_front, random_camera
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ray3d import Camera, InputError, cameras
from ray3d.geometry import camera_pitch, camera_roll, rotation_from_angles


def _seeds(n: int) -> list[int]:
    return list(range(n))


# ------------------------------------------------------------------------------------------ round trips
@pytest.mark.parametrize("seed", _seeds(20))
def test_world_camera_normalized_round_trips(seed):
    rng = np.random.default_rng(seed)
    camera = random_camera(rng)
    points = rng.normal(0, 3, (4, 5, 3))
    np.testing.assert_allclose(camera.camera_to_world(camera.world_to_camera(points)), points, atol=1e-9)
    np.testing.assert_allclose(camera.normalized_to_camera(camera.camera_to_normalized(points)), points, atol=1e-9)
    np.testing.assert_allclose(camera.normalized_to_world(camera.world_to_normalized(points)), points, atol=1e-9)
    composed = camera.camera_to_normalized(camera.world_to_camera(points))
    np.testing.assert_allclose(camera.world_to_normalized(points), composed, atol=1e-12)


@pytest.mark.parametrize("seed", _seeds(20))
def test_normalized_point_is_depth_times_ray_minus_height(seed):
    rng = np.random.default_rng(seed)
    camera = random_camera(rng, distortion=seed % 2 == 0)
    points = points_in_front(camera, rng, 200)
    depth = camera.world_to_camera(points)[:, 2:3]
    rays = camera.pixels_to_rays(camera.project(points))
    expected = depth * rays + np.array([0.0, -camera.camera_height, 0.0])
    np.testing.assert_allclose(camera.world_to_normalized(points), expected, atol=1e-8)


@pytest.mark.parametrize("seed", _seeds(10))
def test_world_up_is_minus_y_and_centre_is_below_origin_without_roll(seed):
    rng = np.random.default_rng(seed)
    camera = random_camera(rng, roll=False)
    up = camera.world_to_normalized(camera.center + np.array([0.0, 0.0, 1.0])) - camera.world_to_normalized(
        camera.center)
    np.testing.assert_allclose(up, [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(camera.world_to_normalized(camera.center), [0.0, -camera.camera_height, 0.0],
                               atol=1e-12)
    # The point on the floor below the camera is the NCS origin.
    floor = camera.center * np.array([1.0, 1.0, 0.0])
    np.testing.assert_allclose(camera.world_to_normalized(floor), [0.0, 0.0, 0.0], atol=1e-12)


def test_centre_maps_to_minus_height_even_with_roll(rng):
    camera = random_camera(rng, roll=True)
    np.testing.assert_allclose(camera.world_to_normalized(camera.center), [0.0, -camera.camera_height, 0.0],
                               atol=1e-12)


@given(yaw=st.floats(-np.pi, np.pi), pitch=st.floats(-1.4, 1.4), roll=st.floats(-0.5, 0.5))
@settings(max_examples=200, deadline=None)
def test_rotation_from_angles_inverts_pitch_and_roll(yaw, pitch, roll):
    R = rotation_from_angles(yaw, pitch, roll)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert camera_pitch(R) == pytest.approx(pitch, abs=1e-9)
    assert camera_roll(R) == pytest.approx(roll, abs=1e-9)


# ---------------------------------------------------------------------------------------- Human3.6M
def test_h36m_s1_54138969_known_values():
    camera = cameras.h36m("S1", "54138969")
    assert camera.camera_height == pytest.approx(1.5634, abs=1e-4)
    assert np.degrees(camera.pitch) == pytest.approx(10.709, abs=1e-3)
    assert camera.name == "h36m:S1:54138969"
    assert camera.image_size == (1000, 1002)


def test_every_h36m_camera_reproduces_the_table():
    table = cameras.h36m_table()["extrinsics"]
    all_cameras = cameras.h36m_all()
    assert len(all_cameras) == 28
    for camera in all_cameras:
        _, subject, camera_id = camera.name.split(":")
        assert camera.camera_height == pytest.approx(table[subject][camera_id]["derived_height_m"], abs=1e-3)
        assert np.degrees(camera.pitch) == pytest.approx(table[subject][camera_id]["derived_pitch_deg"], abs=1e-2)
        assert 1.46 <= camera.camera_height <= 1.64 and 10.5 <= np.degrees(camera.pitch) <= 16.01
        assert abs(np.degrees(camera.roll)) < 6.0


def _image_grid(camera: Camera, step: int = 20) -> np.ndarray:
    width, height = camera.image_size
    u, v = np.meshgrid(np.arange(0, width + 1, step, dtype=float), np.arange(0, height + 1, step, dtype=float))
    return np.stack([u, v], -1).reshape(-1, 2)


@pytest.mark.parametrize("camera", cameras.h36m_all(), ids=lambda c: c.name)
def test_pixels_to_rays_inverts_project_over_the_whole_image(camera):
    pixels = _image_grid(camera)
    rays = camera.pixels_to_camera_rays(pixels)
    assert np.isfinite(rays).all()
    reprojected = camera.project(camera.camera_to_world(2.5 * rays))
    assert np.abs(reprojected - pixels).max() < 1e-3


@pytest.mark.parametrize("camera", cameras.h36m_all()[:4], ids=lambda c: c.name)
def test_lens_model_matches_opencv(camera):
    rng = np.random.default_rng(0)
    points = rng.uniform([-2, -2, 0], [2, 2, 2], (500, 3))
    rvec, _ = cv2.Rodrigues(camera.R)
    expected, _ = cv2.projectPoints(points, rvec, camera.t, camera.K, camera.dist)
    np.testing.assert_allclose(camera.project(points), expected[:, 0], atol=1e-6)
    # OpenCV's iterative undistortion, run to convergence, is the oracle for our Newton inverse.
    pixels = _image_grid(camera, 50)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    undistorted = cv2.undistortPoints(pixels[:, None], camera.K, camera.dist, criteria=criteria)[:, 0]
    np.testing.assert_allclose(camera.pixels_to_camera_rays(pixels)[:, :2], undistorted, atol=1e-7)


def test_pixels_beyond_the_invertible_lens_region_give_nan():
    camera = cameras.h36m("S1", "54138969")
    rays = camera.pixels_to_camera_rays(np.array([[500.0, 500.0], [60000.0, 60000.0]]))
    assert np.isfinite(rays[0]).all() and np.isnan(rays[1]).all()


@given(seed=st.integers(0, 10_000), missing=st.integers(0, 5))
@settings(max_examples=60, deadline=None)
def test_the_opencv_started_inverse_equals_newtons_from_the_distorted_point(seed, missing):
    """numpy points of one camera start from OpenCV's inverse (polished where it fell short); torch and batches
    of cameras run Newton's method from the distorted point: the same rays, NaN in the same places."""
    from ray3d.geometry.distortion import distort, undistort

    rng = np.random.default_rng(seed)
    camera = random_camera(rng, distortion=True)
    xy = rng.uniform(-0.8, 0.8, (40, 2))
    xy[:missing] = np.nan  # missing joints
    distorted = distort(xy, camera.dist)
    fast = undistort(distorted, camera.dist)
    newton = undistort(torch.from_numpy(distorted), torch.tensor(camera.dist)).numpy()
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(newton))
    np.testing.assert_allclose(fast, newton, atol=1e-12, equal_nan=True)
    found = ~np.isnan(fast).any(-1)
    np.testing.assert_allclose(distort(fast[found], camera.dist), distorted[found], atol=1e-13)


@given(dfx=st.floats(-300, 300), dfy=st.floats(-300, 300), dcx=st.floats(-200, 200), dcy=st.floats(-200, 200),
       seed=st.integers(0, 10_000))
@settings(max_examples=100, deadline=None)
def test_rays_do_not_depend_on_intrinsics(dfx, dfy, dcx, dcy, seed):
    """Intrinsic decoupling: the same 3D points give the same rays whatever fx, fy, cx, cy are."""
    rng = np.random.default_rng(seed)
    camera = random_camera(rng, distortion=True)
    other = Camera.from_intrinsics(camera.K[0, 0] + dfx, camera.K[1, 1] + dfy, camera.K[0, 2] + dcx,
                                   camera.K[1, 2] + dcy, camera.dist, camera.R, camera.t, camera.image_size)
    points = points_in_front(camera, rng, 50, max_xy=0.4)
    for rays in (Camera.pixels_to_camera_rays, Camera.pixels_to_rays):
        np.testing.assert_allclose(rays(other, other.project(points)), rays(camera, camera.project(points)),
                                   atol=1e-9)


# -------------------------------------------------------------------------------- numpy / torch / dtypes
def test_float32_and_torch_agree_with_float64(rng):
    camera = random_camera(rng, distortion=True)
    points = points_in_front(camera, rng, 100).reshape(10, 10, 3)
    reference = camera.world_to_normalized(points)
    pixels = camera.project(points)
    rays = camera.pixels_to_rays(pixels)

    out32 = camera.world_to_normalized(points.astype(np.float32))
    assert out32.dtype == np.float32 and out32.shape == (10, 10, 3)
    np.testing.assert_allclose(out32, reference, atol=2e-5 * np.abs(reference).max())

    for dtype, atol in ((torch.float64, 1e-9), (torch.float32, 1e-3)):
        tensor = torch.tensor(points, dtype=dtype)
        assert camera.world_to_normalized(tensor).dtype == dtype
        np.testing.assert_allclose(camera.world_to_normalized(tensor).numpy(), reference, atol=atol)
        np.testing.assert_allclose(camera.project(tensor).numpy(), pixels, atol=atol * 100)
        np.testing.assert_allclose(camera.pixels_to_rays(torch.tensor(pixels, dtype=dtype)).numpy(), rays,
                                   atol=atol)


def test_torch_keeps_autograd(rng):
    camera = random_camera(rng, distortion=True)
    points = torch.tensor(points_in_front(camera, rng, 8), requires_grad=True)
    pixels = camera.project(points)
    rays = camera.pixels_to_rays(pixels)
    (camera.normalized_to_world(camera.world_to_normalized(points)).sum() + rays.sum()).backward()
    assert points.grad is not None and torch.isfinite(points.grad).all()
    # Gradient of a round trip world -> NCS -> world is the identity.
    points.grad = None
    camera.normalized_to_world(camera.world_to_normalized(points))[:, 0].sum().backward()
    np.testing.assert_allclose(points.grad.numpy(), np.tile([1.0, 0.0, 0.0], (8, 1)), atol=1e-12)


def test_integer_and_list_input_become_float():
    camera = cameras.h36m("S9", "55011271")
    assert camera.world_to_camera([[0, 0, 1]]).dtype == np.float64
    assert camera.world_to_camera(torch.tensor([[0, 0, 1]])).dtype == torch.get_default_dtype()


# ------------------------------------------------------------------------------- construction and JSON
def test_dict_round_trip_and_json(tmp_path):
    camera = cameras.h36m("S11", "60457274")
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(camera.to_dict()))
    loaded = Camera.from_dict(json.loads(path.read_text()))
    for field in ("K", "dist", "R", "t"):
        np.testing.assert_array_equal(getattr(loaded, field), getattr(camera, field))
    assert loaded.image_size == camera.image_size and loaded.name == camera.name


def test_from_center_quaternion_reproduces_h36m_extrinsics():
    from scipy.spatial.transform import Rotation

    camera = cameras.h36m("S1", "54138969")
    q = Rotation.from_matrix(camera.R.T).as_quat(scalar_first=True)
    rebuilt = Camera.from_center_quaternion(q, camera.center, *camera.intrinsics, camera.dist, camera.image_size)
    np.testing.assert_allclose(rebuilt.R, camera.R, atol=1e-12)
    np.testing.assert_allclose(rebuilt.t, camera.t, atol=1e-12)


def test_from_center_quaternion_known_videopose3d_values():
    """The published VideoPose3D metadata of S1 / 54138969 (quaternion w, x, y, z; centre in mm)."""
    camera = Camera.from_center_quaternion(
        [0.1407056450843811, -0.1500701755285263, -0.755240797996521, 0.6223280429840088],
        np.array([1841.1070556640625, 4955.28466796875, 1563.4454345703125]) / 1000.0,
        1145.04940458804, 1143.78109572365, 512.541504956548, 515.4514869776, None, (1000, 1002))
    reference = cameras.h36m("S1", "54138969")
    np.testing.assert_allclose(camera.R, reference.R, atol=1e-6)
    np.testing.assert_allclose(camera.center, reference.center, atol=1e-6)


def test_camera_is_immutable():
    camera = cameras.h36m("S1", "54138969")
    with pytest.raises(AttributeError):
        camera.t = np.zeros(3)
    with pytest.raises(ValueError):
        camera.R[0, 0] = 2.0


# ----------------------------------------------------------------------------------------- bad input
def _valid(**overrides):
    fields = dict(K=np.array([[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]]), dist=np.zeros(5),
                  R=rotation_from_angles(0.0, 0.2), t=None, image_size=(1000, 1000))
    fields["t"] = -fields["R"] @ np.array([0.0, 0.0, 1.5])
    fields.update(overrides)
    return fields


@pytest.mark.parametrize("overrides, message", [
    (dict(K=np.array([[0.0, 0, 500], [0, 1000, 500], [0, 0, 1]])), "singular"),
    (dict(K=np.array([[1000.0, 3, 500], [0, 1000, 500], [0, 0, 1]])), "skew"),
    (dict(K=np.eye(4)), "K: expected shape"),
    (dict(R=np.diag([1.0, 1.0, 1.2])), "not a rotation"),
    (dict(R=np.diag([1.0, 1.0, -1.0])), "not a rotation"),
    (dict(t=[0.0, float("nan"), 0.0]), "t: contains NaN"),
    (dict(t=[0.0, 0.0]), "t: expected shape"),
    (dict(dist=[0.1, 0.2, 0.3]), "dist: expected shape"),
    (dict(dist=["a", 0, 0, 0, 0]), "dist: not numeric"),
    (dict(image_size=(0, 100)), "image_size"),
])
def test_bad_camera_fields_raise(overrides, message):
    with pytest.raises(InputError, match=message):
        Camera(**_valid(**overrides))


def test_camera_below_the_ground_raises():
    R = rotation_from_angles(0.0, 0.2)
    with pytest.raises(InputError, match="below the ground"):
        Camera(**_valid(R=R, t=-R @ np.array([0.0, 0.0, -0.3])))


def test_json_camera_missing_a_field_names_it():
    d = cameras.h36m("S1", "54138969").to_dict()
    del d["fy"], d["t"]
    with pytest.raises(InputError, match="missing field.*fy.*t"):
        Camera.from_dict(d)
    with pytest.raises(InputError, match="JSON object"):
        Camera.from_dict([1, 2, 3])


@pytest.mark.parametrize("points, message", [
    (np.zeros((4, 2)), r"expected shape \(\.\.\., 3\)"),
    (np.array([[0.0, np.inf, 1.0]]), "NaN or infinite"),
    (np.float64(3.0), r"expected shape"),
    ([["x", "y", "z"]], "not a numeric array"),
    (torch.tensor([[float("nan"), 0.0, 1.0]]), "NaN or infinite"),
])
def test_bad_points_raise(points, message):
    with pytest.raises(InputError, match=message):
        cameras.h36m("S1", "54138969").world_to_normalized(points)


def test_bad_pixels_raise():
    camera = cameras.h36m("S1", "54138969")
    for rays in (camera.pixels_to_rays, camera.pixels_to_camera_rays):
        with pytest.raises(InputError, match=r"pixels: expected shape \(\.\.\., 2\)"):
            rays(np.zeros((3, 3)))


def test_unknown_h36m_camera_raises():
    with pytest.raises(InputError, match="unknown subject 'S2'"):
        cameras.h36m("S2", "54138969")
    with pytest.raises(InputError, match="unknown camera id"):
        cameras.h36m("S1", "123")


# ------------------------------------------------------------------------------- gravity-aligned NCS
@pytest.mark.parametrize("seed", _seeds(10))
def test_gravity_aligned_ncs_removes_roll(seed):
    rng = np.random.default_rng(seed)
    camera = random_camera(rng, distortion=True, roll=True)
    assert abs(camera.roll) > 1e-4
    up = camera.world_to_normalized(camera.center + [0.0, 0.0, 1.0], remove_roll=True) - camera.world_to_normalized(
        camera.center, remove_roll=True)
    np.testing.assert_allclose(up, [0.0, -1.0, 0.0], atol=1e-12)
    floor_below = camera.center * np.array([1.0, 1.0, 0.0])
    np.testing.assert_allclose(camera.world_to_normalized(floor_below, remove_roll=True), 0.0, atol=1e-12)
    # The paper's NCS keeps the roll: its origin is off the point below the camera.
    assert np.linalg.norm(camera.world_to_normalized(floor_below)) > 1e-4
    points = points_in_front(camera, rng, 50)
    np.testing.assert_allclose(camera.normalized_to_world(camera.world_to_normalized(points, True), True), points,
                               atol=1e-9)
    depth = camera.world_to_camera(points)[:, 2:3]
    rays = camera.pixels_to_rays(camera.project(points), remove_roll=True)
    np.testing.assert_allclose(camera.world_to_normalized(points, True),
                               depth * rays + [0.0, -camera.camera_height, 0.0], atol=1e-8)


def test_h36m_roll_moves_the_paper_ncs_origin_by_up_to_14_cm():
    offsets = [np.linalg.norm(c.world_to_normalized(c.center * [1.0, 1.0, 0.0])[[0, 2]]) for c in cameras.h36m_all()]
    assert 0.10 < max(offsets) < 0.16


def test_from_height_pitch_agrees_with_the_full_model():
    camera = Camera.from_height_pitch(2.4, 25.0, (1920, 1080), roll_deg=2.0, hfov_deg=70.0)
    assert camera.camera_height == pytest.approx(2.4)
    assert np.degrees(camera.pitch) == pytest.approx(25.0) and np.degrees(camera.roll) == pytest.approx(2.0)
    focal = 960 / np.tan(np.radians(35.0))
    np.testing.assert_allclose(camera.intrinsics, [focal, focal, 960, 540])
    full = Camera.from_pose([0, 0, 2.4], 0.0, np.radians(25), np.radians(2), focal, focal, 960, 540, (1920, 1080))
    np.testing.assert_allclose(camera.R, full.R, atol=1e-12)
    np.testing.assert_allclose(camera.t, full.t, atol=1e-12)
    # The floor point the optical axis hits is straight ahead at height / tan(pitch).
    ahead = np.array([[2.4 / np.tan(np.radians(25.0)), 0.0, 0.0]])
    np.testing.assert_allclose(Camera.from_height_pitch(2.4, 25.0, (1920, 1080), focal_px=1000).project(ahead),
                               [[960, 540]], atol=1e-9)
    with pytest.raises(InputError, match="exactly one of focal_px and hfov_deg"):
        Camera.from_height_pitch(2.4, 25.0, (1920, 1080))


@settings(max_examples=50, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-1.2, 1.2), st.floats(0.5, 40.0))
def test_a_camera_placed_looking_at_a_point_sees_it_on_its_axis(yaw, pitch, distance):
    from ray3d.geometry import centre_looking_at

    target = np.array([1.0, -2.0, 1.5])
    centre = centre_looking_at(target, yaw, pitch, distance)
    assume(centre[2] > 0.05)  # cameras stand above the floor
    camera = Camera.from_pose(centre, yaw, pitch, 0.0, 1000.0, 1000.0, 500.0, 400.0, (1000, 800))
    np.testing.assert_allclose(camera.world_to_camera(target), [0.0, 0.0, distance], atol=1e-9)
    np.testing.assert_allclose(camera.project(target), [500.0, 400.0], atol=1e-6)
    assert camera.sees(target) and not camera.sees(centre - (target - centre))  # behind it


def test_the_floor_frame_keeps_the_view_height_pitch_and_roll():
    camera = cameras.h36m("S9", "54138969")
    floor = camera.in_floor_frame()
    assert floor.camera_height == pytest.approx(camera.camera_height)
    assert floor.pitch == pytest.approx(camera.pitch) and floor.roll == pytest.approx(camera.roll)
    np.testing.assert_allclose(floor.center, [0.0, 0.0, camera.camera_height], atol=1e-9)
    points = np.array([[0.5, 0.2, 1.0], [-1.0, 2.0, 0.1]]) + camera.center * [1, 1, 0]
    np.testing.assert_allclose(floor.project(floor.camera_to_world(camera.world_to_camera(points))),
                               camera.project(points), atol=1e-6)


@pytest.mark.parametrize("value, expected", [("1920x1080", (1920, 1080)), ((640, 480), (640, 480)),
                                             ("800X600", (800, 600))])
def test_image_sizes_parse(value, expected):
    from ray3d.geometry import parse_image_size

    assert parse_image_size(value) == expected


@pytest.mark.parametrize("value, message", [("1920", "WIDTHxHEIGHT"), ("0x10", "positive"), (None, "WIDTHxHEIGHT"),
                                            ((1, 2, 3), "WIDTHxHEIGHT"), ("axb", "WIDTHxHEIGHT")])
def test_bad_image_sizes_name_the_field(value, message):
    from ray3d.geometry import parse_image_size

    with pytest.raises(InputError, match=f"--image-size: .*{message}"):
        parse_image_size(value, "--image-size")


def test_pinhole_intrinsics_from_focal_or_field_of_view():
    from ray3d.geometry import pinhole_intrinsics

    assert pinhole_intrinsics((1000, 800), focal_px=700.0) == (700.0, 700.0, 500.0, 400.0)
    fx, fy, cx, cy = pinhole_intrinsics("1000x800", hfov_deg=90.0)
    assert fx == pytest.approx(500.0) and (cx, cy) == (500.0, 400.0)
    with pytest.raises(InputError, match="exactly one of focal_px and hfov_deg"):
        pinhole_intrinsics((1000, 800))


def test_a_camera_batch_repeats_one_camera_and_packs_height_and_pitch():
    from ray3d.geometry import CameraBatch

    camera = cameras.h36m("S9", "54138969")
    batch = CameraBatch.repeated(camera, 3)
    assert len(batch) == 3 and batch.has_distortion and batch.image_size == camera.image_size
    np.testing.assert_allclose(batch.height_pitch, [[camera.camera_height, camera.pitch]] * 3)
    again = batch.camera(2)
    np.testing.assert_allclose(again.R, camera.R)
    np.testing.assert_allclose(again.t, camera.t)
    with pytest.raises(InputError, match="no cameras"):
        CameraBatch.from_cameras([])


def _toml_camera(name: str, camera: Camera) -> str:
    rvec = cv2.Rodrigues(camera.R)[0].ravel()
    return (f'[{name}]\nname = "{name}"\nsize = [{camera.image_size[0]}.0, {camera.image_size[1]}.0]\n'
            f"matrix = {camera.K.tolist()}\ndistortions = {camera.dist[:4].tolist()}\n"
            f"rotation = {rvec.tolist()}\ntranslation = {camera.t.tolist()}\nfisheye = false\n\n")


def test_a_calibration_toml_projects_as_opencv_does(tmp_path, rng):
    """Pose2Sim / Anipose TOML: Rodrigues rotation, world -> camera translation, OpenCV distortion."""
    from ray3d.io.camera_files import read_camera

    first, second = cameras.h36m("S9", "54138969"), cameras.h36m("S11", "60457274")
    path = tmp_path / "calibration.toml"
    path.write_text(_toml_camera("cam_01", first) + _toml_camera("cam_02", second) + "[metadata]\nadjusted = false\n")
    for spec, truth, name in ((f"{path}:cam_02", second, "cam_02"), (f"{path}:cam02", second, "cam_02"),
                              (f"{path}:cam_01", first, "cam_01")):
        camera = read_camera(spec)
        points = points_in_front(truth, rng, 40, max_xy=0.4)
        rvec, _ = cv2.Rodrigues(truth.R)
        expected, _ = cv2.projectPoints(points, rvec, truth.t, truth.K, truth.dist[:4])
        np.testing.assert_allclose(camera.project(points), expected[:, 0], atol=1e-6)
        assert camera.name == name and camera.image_size == truth.image_size
    with pytest.raises(InputError, match="holds cameras cam_01, cam_02; name one"):
        read_camera(path)
    with pytest.raises(InputError, match="no camera 'cam_09'"):
        read_camera(f"{path}:cam_09")
    path.write_text(_toml_camera("solo", first).replace("fisheye = false", "fisheye = true"))
    with pytest.raises(InputError, match="fisheye"):
        read_camera(path)


def test_rotations_rounded_to_seven_digits_are_accepted_and_made_orthonormal():
    camera = cameras.h36m("S9", "54138969")
    rounded = np.round(camera.R, 7)
    deviation = np.abs(rounded @ rounded.T - np.eye(3)).max()
    assert 1e-9 < deviation < 1e-4
    kept = Camera.from_intrinsics(*camera.intrinsics, camera.dist, rounded, camera.t, camera.image_size)
    np.testing.assert_allclose(kept.R @ kept.R.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(kept.R, camera.R, atol=1e-6)
    with pytest.raises(InputError, match=r"not a rotation \(\|R R\^T - I\| = 2\.0\de-03"):
        Camera.from_intrinsics(*camera.intrinsics, camera.dist, camera.R * 1.001, camera.t, camera.image_size)


def test_a_camera_says_what_makes_it_unusable_or_implausible(tmp_path):
    """Real calibrations raise no doubt; a lens whose distortion turns back inside the image is unusable (and
    refused by the job's camera builder); a camera looking up from the floor, a 1-degree lens (k1 = 1e6) and a
    principal point a million pixels out are implausible (issue 49)."""
    import json

    from ray3d import cameras
    from ray3d.io.camera_files import camera_from_options

    assert cameras.h36m("S9", "54138969").doubts() == ((), ())
    base = Camera.from_height_pitch(3.0, 20.0, (1280, 720), hfov_deg=60.0)
    folding = Camera(base.K, [-0.9, 0, 0, 0, 0], base.R, base.t, base.image_size, "folding")
    unusable, _ = folding.doubts()
    assert len(unusable) == 1 and "turns back" in unusable[0] and "folding" in unusable[0]
    path = tmp_path / "folding.json"
    path.write_text(json.dumps(folding.to_dict()))
    with pytest.raises(InputError, match="turns back"):
        camera_from_options(str(path))
    looking_up = Camera.from_height_pitch(0.3, -30.0, (1000, 1002), hfov_deg=50.0)
    squeezed = Camera(base.K, [1e6, 0, 0, 0, 0], base.R, base.t, base.image_size, "squeezed")
    K = base.K.copy()
    K[0, 2] = 1e6
    off_centre = Camera(K, base.dist, base.R, base.t, base.image_size, "off")
    for camera, needle in ((looking_up, "above the horizon"), (squeezed, "degrees across its image"),
                           (off_centre, "principal point")):
        unusable, implausible = camera.doubts()
        assert not unusable and any(needle in doubt for doubt in implausible), (needle, implausible)
    assert base.doubts() == ((), ())
