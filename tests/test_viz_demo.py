"""Visualisation and the demo: GIF frames, metric plots, the HTML viewer in headless Chromium, the demo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from browser import console_errors, needs_chromium, screenshot
from PIL import Image

from ray3d import InputError, cameras
from ray3d.cli import main
from ray3d.demo import demo_clip, run_demo
from ray3d.io.keypoints import Keypoints, read_keypoints, write_keypoints_json
from ray3d.io.world import LiftResult, World, write_world
from ray3d.video.frames import read_video_info
from ray3d.viz.animation import render_frames, save_animation
from ray3d.viz.html_viewer import write_viewer
from ray3d.viz.plots import plot_sweep


def test_gif_has_one_frame_per_stride(tmp_path):
    truth = demo_clip()[:20]
    camera = cameras.h36m("S9", "54138969")
    images = list(render_frames({"ray3d": truth + 0.02}, camera, {"ray3d": camera.project(truth)}, truth, stride=5,
                                size_px=360))
    assert len(images) == 4
    path = save_animation(images, tmp_path / "a.gif", fps=12)
    with Image.open(path) as gif:
        assert gif.n_frames == 4
        pixels = np.asarray(gif.convert("RGB"))
    assert (pixels < 200).any() and (pixels > 250).any()  # something is drawn on a white background
    with pytest.raises(Exception, match="already exists"):
        save_animation(images, path, fps=12)
    video = save_animation(iter(images), tmp_path / "a.mp4", fps=12)  # streamed through OpenCV, no ffmpeg
    info = read_video_info(video)
    assert info.frames == 4 and info.image_size == images[0].size


def test_the_floor_ellipse_of_a_position_uncertainty():
    from ray3d import Camera
    from ray3d.viz.html_viewer import floor_ellipses

    level = Camera.from_height_pitch(1.0, 0.0, (640, 480), hfov_deg=60.0)  # looks along +x at the root's height
    joints = np.zeros((2, 17, 3))
    joints[:, 0] = [[5.0, 0.0, 1.0], [5.0, 0.0, 6.0]]  # level with the camera, and 45 deg up from it
    track = LiftResult(joints, np.zeros((2, 17), bool), 30.0, np.arange(2), position_sd=np.array([[0.5, 0.1]] * 2))
    ellipses = floor_ellipses(track, level)
    np.testing.assert_allclose(ellipses[0], [0.5, 0.1, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(ellipses[1, 0], np.hypot(0.5, 0.1) / np.sqrt(2), atol=1e-9)
    assert floor_ellipses(joints, level) is None and floor_ellipses(track, None) is None


def test_sweep_plot_is_a_png(tmp_path):
    path = plot_sweep([1, 2, 3], {"a": [3, 2, 1], "b": [1, 2, 3]}, "pitch (deg)", "MRPE (mm)", "t", tmp_path / "p.png")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size[0] > 300


@needs_chromium
def test_html_viewer_renders_in_headless_chromium(tmp_path):
    truth = demo_clip()[:30]
    shifted = LiftResult(truth + 0.3, np.zeros((30, 17), bool), 30.0, np.arange(30),
                         position_sd=np.tile([0.4, 0.05], (30, 1)))  # drawn with its uncertainty on the floor
    viewer = write_viewer(tmp_path / "viewer.html", {"truth": truth, "shifted": shifted}, fps=30.0,
                          camera=cameras.h36m("S9", "54138969"))
    html = viewer.read_text()
    assert "http://" not in html and "https://" not in html  # self-contained: nothing to fetch
    for view in ("", "#view=top", "#view=side", "#view=camera"):
        assert console_errors(viewer, view) == "[]", view
        pixels = screenshot(viewer.as_uri() + view, tmp_path / f"shot{view[6:]}.png", size="1000,700")
        canvas = pixels[80:640, 20:760]  # below the bar, left of the floor plan
        assert canvas.std() > 5, view  # not blank
        red = (canvas[..., 0] > 180) & (canvas[..., 1] < 90) & (canvas[..., 2] < 90)
        blue = (canvas[..., 2] > 180) & (canvas[..., 0] < 90)
        assert red.sum() > 30 and blue.sum() > 30, view  # both sequences' skeletons are drawn in every view


def test_demo_runs_end_to_end_on_a_short_clip(tmp_path, tiny_checkpoint):
    result = run_demo(tmp_path / "demo", str(tiny_checkpoint), frames=24, gif_stride=12)
    assert set(result["table"]) >= {str(tiny_checkpoint), "rfrh"}
    assert result["viewer"].is_file() and result["animation"].is_file()
    assert all(np.isfinite(v["mrpe_mm"]) for v in result["table"].values())
    data = json.loads(result["viewer"].read_text().split("const DATA = ", 1)[1].split(";\n", 1)[0])
    assert data["last"] - data["first"] + 1 == 24 and "truth" in data["sequences"]


def test_demo_cli(tmp_path, tiny_checkpoint, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--checkpoint", str(tiny_checkpoint), "--frames", "12"]) == 0
    out = capsys.readouterr().out
    assert "Abs-MPJPE" in out and "rfrh" in out and "viewer.html" in out


def test_viz_cli_from_lift_outputs(tmp_path, tiny_checkpoint):
    truth = demo_clip()[:16]
    camera = cameras.h36m("S9", "54138969")
    np.savez(tmp_path / "k.npz", keypoints=camera.project(truth))
    world = tmp_path / "world.npz"
    assert main(["lift", "--keypoints", str(tmp_path / "k.npz"), "--camera", "h36m:S9:54138969", "--out", str(world),
                 "--checkpoint", str(tiny_checkpoint)]) == 0
    assert main(["viz", str(world), "--camera", "h36m:S9:54138969", "--html", str(tmp_path / "v.html"),
                 "--animation", str(tmp_path / "v.gif"), "--stride", "8"]) == 0
    assert "const DATA" in (tmp_path / "v.html").read_text()
    with Image.open(tmp_path / "v.gif") as gif:
        assert gif.n_frames == 2
    assert main(["viz", str(world)]) == 2


def test_viz_draws_every_track_at_the_world_files_rate_with_its_camera(tmp_path):
    """Two people in one world file (one starting later, with filled-in frames): the viewer and the animation
    hold both, at the file's 25 frames/s, through the file's camera, without --camera."""
    camera = cameras.h36m("S9", "54138969")
    clip = demo_clip()[:20]
    filled = np.zeros((12, 17), dtype=bool)
    filled[4:6] = True
    world = World({"0": LiftResult(clip, np.zeros((20, 17), dtype=bool), 25.0, np.arange(20)),
                   "7": LiftResult(clip[:12] + [1.0, 0.5, 0.0], filled, 25.0, np.arange(6, 18))}, camera, "test")
    path = write_world(tmp_path / "people.json", world)
    assert main(["viz", str(path), "--html", str(tmp_path / "v.html"), "--animation", str(tmp_path / "v.gif"),
                 "--stride", "5"]) == 0
    data = json.loads((tmp_path / "v.html").read_text().split("const DATA = ", 1)[1].split(";\n", 1)[0])
    assert set(data["sequences"]) == {"0", "7"} and data["fps"] == 25.0
    assert data["sequences"]["7"]["start"] == 6 and data["sequences"]["7"]["filled"][4:6] == [True, True]
    assert (data["first"], data["last"]) == (0, 19) and len(data["camera_lines"]) == 8
    with Image.open(tmp_path / "v.gif") as gif:
        assert gif.n_frames == 4  # frames 0, 5, 10, 15 of the union of both tracks
    # The 2D input drawn under the lifted joints: each track's detections at its own frames.
    pixels = camera.project(clip[:12] + [1.0, 0.5, 0.0])
    keypoints = Keypoints(pixels, np.ones((12, 17)), np.arange(6, 18), np.full(12, 7), "h36m17", 25.0, "test")
    write_keypoints_json(tmp_path / "k.json", keypoints)
    aligned = read_keypoints(tmp_path / "k.json").h36m_pixels("7", np.arange(4, 10))
    assert np.isnan(aligned[:2]).all() and np.allclose(aligned[2:], pixels[:4], atol=1e-3)
    assert main(["viz", str(path), "--keypoints", str(tmp_path / "k.json"), "--animation", str(tmp_path / "k.gif"),
                 "--stride", "10"]) == 0
    assert main(["viz", str(path), "--track", "7", "--html", str(tmp_path / "one.html")]) == 0
    one = json.loads((tmp_path / "one.html").read_text().split("const DATA = ", 1)[1].split(";\n", 1)[0])
    assert set(one["sequences"]) == {"7"} and one["first"] == 6


def test_animations_are_written_as_the_frames_come_not_held(tmp_path, capsys):
    rng = np.random.default_rng(0)
    written, images = [], []

    def frames():
        for k in range(40):
            partial = [p.stat().st_size for p in tmp_path.glob(".a.gif.*")]
            written.append(partial[0] if partial else 0)
            images[:] = [np.clip(6 * k + rng.normal(0, 40, (120, 160, 3)), 0, 255).astype(np.uint8)]
            yield Image.fromarray(images[0])

    save_animation(frames(), tmp_path / "a.gif", fps=20)
    # Each frame is encoded to the file before the next is asked for (beyond the write buffer): none is held.
    assert all(b > a for a, b in zip(written[2:], written[3:])), written
    with Image.open(tmp_path / "a.gif") as gif:
        assert gif.n_frames == 40 and gif.info["loop"] == 0 and gif.info["duration"] == 50
        gif.seek(39)  # its own palette: close to the last image given
        assert np.abs(np.asarray(gif.convert("RGB")).astype(int) - images[0]).mean() < 12
    with pytest.raises(InputError, match="no frames"):
        save_animation(iter(()), tmp_path / "empty.gif", fps=20)
    assert not (tmp_path / "empty.gif").exists()
    camera = cameras.h36m("S9", "54138969")
    world = write_world(tmp_path / "w.npz", World({"0": LiftResult(demo_clip()[:5], np.zeros((5, 17), dtype=bool),
                                                                   60.0, np.arange(5))}, camera, "test"))
    assert main(["viz", str(world), "--animation", str(tmp_path / "x.gif"), "--stride", "0"]) == 2
