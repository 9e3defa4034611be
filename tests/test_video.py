"""The video pipeline on a generated video: a stub detector exercises every step (reading frames, detecting,
lifting, the world file, the detections, the viewer, the overlay video); the real MediaPipe detector runs when
the video extra is installed."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from ray3d import Camera, InputError, Lifter
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.world import read_world
from ray3d.skeleton import H36M17
from ray3d.video import DETECTORS, lift_video, read_video_info

SIZE, FPS, FRAMES = (640, 480), 30.0, 36


def _scene():
    camera = Camera.from_height_pitch(2.0, 15.0, SIZE, hfov_deg=70.0)
    world = demo_clip()[:FRAMES] + np.array([5.0, 0.0, 0.0])
    return camera, world, camera.project(world)


def _render(path, pixels):
    """A video of a stick figure: white bones on grey, the pelvis a filled disc."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE)
    for frame_pixels in pixels:
        frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
        for child, parent in enumerate(H36M17.parents):
            if parent >= 0:
                a, b = (tuple(int(v) for v in frame_pixels[i]) for i in (child, parent))
                cv2.line(frame, a, b, (255, 255, 255), 4)
        cv2.circle(frame, tuple(int(v) for v in frame_pixels[0]), 8, (255, 255, 255), -1)
        writer.write(frame)
    writer.release()
    return path


class StubDetector:
    """Returns the known pixels of each frame after checking the frame shows the figure there; misses
    everybody in frames 10-12 and the left wrist in frame 20."""

    layout = "h36m17"

    def __init__(self, pixels):
        self.pixels, self.calls = pixels, 0

    def __call__(self, frame):
        assert frame.shape == (SIZE[1], SIZE[0], 3) and frame.dtype == np.uint8
        t = self.calls
        self.calls += 1
        u, v = (int(round(x)) for x in self.pixels[t, 0])
        assert frame[v, u].mean() > 200, "the pelvis disc is not where the stub expects it"
        pixels, confidences = self.pixels[t].copy(), np.ones(17)
        if 10 <= t <= 12:
            return np.full((17, 2), np.nan), np.zeros(17)
        if t == 20:
            confidences[13] = 0.0
        return pixels, confidences


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    camera, world, pixels = _scene()
    return _render(tmp_path_factory.mktemp("video") / "walk.mp4", pixels), camera, world, pixels


def test_the_pipeline_writes_every_output_and_equals_lifting_the_detections(video, tmp_path):
    path, camera, world, pixels = video
    info = read_video_info(path)
    assert info.image_size == SIZE and info.frames == FRAMES and info.fps == pytest.approx(FPS)
    lifter = Lifter.load()
    result = lift_video(path, camera, tmp_path / "out", StubDetector(pixels), lifter, progress=False)
    assert set(result.files) == {"world", "keypoints", "viewer", "overlay"}
    assert result.lifted.interpolated[10:13].all() and result.lifted.interpolated[20, 13]
    direct = lifter.lift(result.keypoints, camera, result.confidences, FPS, "h36m17").joints
    np.testing.assert_allclose(result.lifted.joints, direct)
    saved = read_world(result.files["world"])
    np.testing.assert_allclose(saved.track().joints, result.lifted.joints, atol=1e-5)
    assert np.abs(result.lifted.joints - world).mean() < 0.5  # metres: a sanity bound, not an accuracy claim
    # The detections can be lifted again without detecting: the frames without anybody are left out.
    detections = json.loads(result.files["keypoints"].read_text())
    assert detections["layout"] == "h36m17" and len(detections["detections"]) == FRAMES - 3
    assert main(["lift", "--keypoints", str(result.files["keypoints"]), "--camera-height", "2", "--pitch", "15",
                 "--hfov", "70", "--image-size", "640x480", "--out", str(tmp_path / "again.json")]) == 0
    again = read_world(tmp_path / "again.json")
    np.testing.assert_allclose(again.track().joints, result.lifted.joints, atol=1e-4)
    assert "ray3d: walk.mp4" in result.files["viewer"].read_text()
    overlay = read_video_info(result.files["overlay"])
    assert overlay.frames == FRAMES and overlay.image_size == SIZE


def test_the_pipeline_refuses_what_it_cannot_use(video, tmp_path):
    path, camera, world, pixels = video
    lift_video(path, camera, tmp_path, StubDetector(pixels), overlay=False, progress=False)
    with pytest.raises(InputError, match="already exist"):
        lift_video(path, camera, tmp_path, StubDetector(pixels), overlay=False, progress=False)
    other = Camera.from_height_pitch(2.0, 15.0, (1280, 720), hfov_deg=70.0)
    with pytest.raises(InputError, match=r"image size \(1280, 720\) but .*640x480"):
        lift_video(path, other, tmp_path / "b", StubDetector(pixels), progress=False)

    class Blind:
        layout = "h36m17"

        def __call__(self, frame):
            return np.full((17, 2), np.nan), np.zeros(17)

    with pytest.raises(InputError, match="found nobody"):
        lift_video(path, camera, tmp_path / "c", Blind(), progress=False)
    (tmp_path / "notes.mp4").write_text("not a video")
    with pytest.raises(InputError, match="notes.mp4"):
        lift_video(tmp_path / "notes.mp4", camera, tmp_path / "d", Blind(), progress=False)


def test_video_cli_with_a_registered_detector(video, tmp_path, monkeypatch, capsys):
    path, camera, world, pixels = video
    monkeypatch.setitem(DETECTORS, "stub", lambda: StubDetector(pixels))
    assert main(["video", str(path), "--camera-height", "2", "--pitch", "15", "--hfov", "70", "--detector", "stub",
                 "--format", ".csv", "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert f"{FRAMES} frames, a person found in {FRAMES - 3}" in out
    assert (tmp_path / "out" / "world.csv").is_file() and (tmp_path / "out" / "overlay.mp4").is_file()
    assert main(["video", str(path), "--camera-height", "2", "--pitch", "15", "--hfov", "70", "--detector", "yolo",
                 "--out", str(tmp_path / "x")]) == 2
    assert "unknown detector 'yolo'" in capsys.readouterr().err


def test_mediapipe_detector_on_generated_frames():
    pytest.importorskip("mediapipe", reason="the video extra is not installed: pip install 'ray3d[video]'")
    from ray3d.video import MediaPipeDetector

    camera, world, pixels = _scene()
    detector = MediaPipeDetector()
    frame = np.full((SIZE[1], SIZE[0], 3), 60, np.uint8)
    landmarks, confidences = detector(frame)  # nobody in an empty frame
    assert landmarks.shape == (33, 2) and confidences.shape == (33,)
    assert np.isnan(landmarks).all() and not confidences.any()
    detector.close()
