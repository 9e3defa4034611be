"""One front end for jobs: a camera from options, the lifting and video options as checked records, and the
detections of one track as a named record."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import Camera, InputError, cameras
from ray3d.cli import main
from ray3d.geometry.floor import FLAT_FLOOR
from ray3d.io.camera_files import camera_from_options, save_cameras
from ray3d.io.detections import TrackDetections
from ray3d.lifting.options import LiftOptions, VideoOptions


def test_a_camera_file_or_a_placed_camera(tmp_path):
    h36m = cameras.h36m("S9", "54138969")
    save_cameras(tmp_path / "cam.json", [h36m])
    np.testing.assert_allclose(camera_from_options(tmp_path / "cam.json").R, h36m.R)
    assert camera_from_options("h36m:S9:54138969").name == h36m.name
    placed = camera_from_options(camera_height=3.0, pitch=20.0, image_size="1280x720", hfov=60.0)
    expected = Camera.from_height_pitch(3.0, 20.0, (1280, 720), hfov_deg=60.0)
    np.testing.assert_allclose(placed.K, expected.K)
    np.testing.assert_allclose(placed.center, [0.0, 0.0, 3.0], atol=1e-12)
    # A video's own size is the default; a size given wins over it.
    assert camera_from_options(camera_height=3.0, pitch=20.0, focal=900.0, default_image_size=(640, 480)
                               ).image_size == (640, 480)
    assert camera_from_options(camera_height=3.0, pitch=20.0, focal=900.0, image_size=(800, 600),
                               default_image_size=(640, 480)).image_size == (800, 600)


@pytest.mark.parametrize("options, message, arguments", [
    (dict(camera="h36m:S9:54138969", pitch=10.0), "not both", ("camera", "pitch")),
    (dict(camera="h36m:S9:54138969", roll=0.0), "not both", ("camera", "roll")),
    (dict(camera_height=3.0, pitch=20.0, hfov=60.0), "no camera", ("camera", "camera_height", "pitch", "image_size",
                                                                  "hfov")),
    (dict(camera_height=3.0, pitch=20.0, image_size="1280", hfov=60.0), "image_size", ("image_size",)),
    (dict(), "no camera", ("camera", "camera_height", "pitch", "image_size", "hfov")),
])
def test_a_camera_from_bad_options_is_refused_naming_its_arguments(options, message, arguments):
    with pytest.raises(InputError, match=message) as caught:
        camera_from_options(**options)
    assert caught.value.arguments == arguments


def test_the_command_line_names_the_flags_of_a_camera_given_twice(tmp_path, capsys):
    np.savez(tmp_path / "kp.npz", keypoints=np.full((5, 17, 2), 500.0), layout="h36m17")
    code = main(["lift", "--keypoints", str(tmp_path / "kp.npz"), "--camera", "h36m:S9:54138969", "--pitch", "10",
                 "--out", str(tmp_path / "w.json")])
    assert code == 2 and "(--camera, --pitch)" in capsys.readouterr().err


def test_lift_options_are_checked_once_and_say_none_as_none():
    assert LiftOptions(smooth_2d="none", smooth_3d="none").lift_arguments() == {
        "smooth_2d": None, "smooth_3d": None, "flip_test": False, "refine": True, "floor": FLAT_FLOOR,
        "floor_z": None, "seen_before": ()}
    assert LiftOptions().smooth_3d == "savgol" and LiftOptions().frame == "world"
    with pytest.raises(InputError, match="seen_before: SizeEvidence and SeenTwice"):
        LiftOptions(seen_before=[0.1])
    with pytest.raises(InputError, match="smooth_3d: unknown smoothing 'kalman'"):
        LiftOptions(smooth_3d="kalman")
    with pytest.raises(InputError, match="frame must be one of world, camera"):
        LiftOptions(frame="body")


@pytest.mark.parametrize("options, message", [
    (dict(max_gap_s=-1.0), "max_gap_s must be a duration"), (dict(min_track_s=float("nan")), "min_track_s"),
    (dict(start=-1), "start must be a frame index"), (dict(frames=0), "frames must be at least 1"),
])
def test_bad_video_options_are_refused(options, message):
    with pytest.raises(InputError, match=message):
        VideoOptions(**options)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=25, unique=True), st.randoms(use_true_random=False))
def test_a_track_made_dense_has_every_frame_in_order_and_nothing_where_it_was_not_seen(frames, shuffle):
    order = list(frames)
    shuffle.shuffle(order)
    pixels = np.array(order, dtype=float)[:, None, None] * np.ones((1, 3, 2))
    confidences = np.full((len(order), 3), 0.5)
    span, dense, scores = TrackDetections(np.array(order), pixels, confidences).dense()
    np.testing.assert_array_equal(span, np.arange(min(frames), max(frames) + 1))
    seen = np.isin(span, frames)
    np.testing.assert_array_equal(dense[seen, 0, 0], span[seen])
    assert np.isnan(dense[~seen]).all() and (scores[~seen] == 0).all() and (scores[seen] == 0.5).all()
    assert TrackDetections(np.array(order), pixels).dense()[2] is None
