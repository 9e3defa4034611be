"""The 2D keypoints beside the 3D world view, frame by frame: ground grid, camera frustum, trajectory trail;
ground truth dashed, prediction solid; the person's left in blue and right in red (as the paper's figures).
GIF through Pillow (no ffmpeg needed); MP4 when an ffmpeg binary is present."""

from __future__ import annotations

import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from ray3d.errors import InputError  # noqa: E402
from ray3d.geometry import Camera  # noqa: E402
from ray3d.io.atomic import atomic_path  # noqa: E402
from ray3d.skeleton import H36M17  # noqa: E402

LEFT, RIGHT, CENTRE = "#1f5fd6", "#d62f2f", "#444444"


def bone_colour(child: int) -> str:
    name = H36M17.joint_names[child]
    return LEFT if name.startswith("l_") else RIGHT if name.startswith("r_") else CENTRE


def frustum_lines(camera: Camera, depth: float = 0.6) -> list[np.ndarray]:
    """World line segments (2, 3) drawing the camera as a small pyramid pointing where it looks."""
    width, height = camera.image_size
    corners_px = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=float)
    corners = camera.camera_to_world(depth * camera.pixels_to_rays(corners_px, frame="camera"))
    centre = camera.center
    return [np.stack([centre, c]) for c in corners] + [np.stack([corners[i], corners[(i + 1) % 4]]) for i in range(4)]


def render_frames(pixels: np.ndarray, predicted: np.ndarray, camera: Camera, target: np.ndarray | None = None,
                  stride: int = 1, size_px: int = 720) -> list[Image.Image]:
    """One image per ``stride``-th frame: pixels (T, 17, 2), predicted / target world joints (T, 17, 3)."""
    frames = range(0, len(predicted), stride)
    everything = np.concatenate([predicted.reshape(-1, 3), camera.center[None]]
                                + ([target.reshape(-1, 3)] if target is not None else []))
    low, high = everything.min(axis=0), everything.max(axis=0)
    centre = (low + high) / 2
    reach = max(1.5, (high[:2] - low[:2]).max() / 2 + 0.5)
    fig = plt.figure(figsize=(size_px / 50, size_px / 100), dpi=100)
    image_axes = fig.add_subplot(1, 2, 1)
    world_axes = fig.add_subplot(1, 2, 2, projection="3d")
    grid = np.arange(np.floor(centre[0] - reach), np.ceil(centre[0] + reach) + 0.01, 0.5)
    grid_y = np.arange(np.floor(centre[1] - reach), np.ceil(centre[1] + reach) + 0.01, 0.5)
    images = []
    for t in frames:
        image_axes.cla()
        world_axes.cla()
        width, height = camera.image_size
        image_axes.set_xlim(0, width)
        image_axes.set_ylim(height, 0)
        image_axes.set_aspect("equal")
        image_axes.set_title(f"2D keypoints (frame {t})", fontsize=9)
        for child, parent in enumerate(H36M17.parents):
            if parent >= 0:
                image_axes.plot(*pixels[t, [child, parent]].T, color=bone_colour(child), lw=2)
        for x in grid:
            world_axes.plot([x, x], [grid_y[0], grid_y[-1]], [0, 0], color="#dddddd", lw=0.5)
        for y in grid_y:
            world_axes.plot([grid[0], grid[-1]], [y, y], [0, 0], color="#dddddd", lw=0.5)
        world_axes.plot(*predicted[: t + 1, 0, :2].T, np.zeros(t + 1), color="#2a9d3c", lw=1)  # trail on floor
        for line in frustum_lines(camera):
            world_axes.plot(*line.T, color="#888888", lw=0.8)
        for pose, style in ((target, "--"), (predicted, "-")):
            if pose is None:
                continue
            for child, parent in enumerate(H36M17.parents):
                if parent >= 0:
                    world_axes.plot(*pose[t, [child, parent]].T, style, color=bone_colour(child), lw=2)
        world_axes.set_xlim(centre[0] - reach, centre[0] + reach)
        world_axes.set_ylim(centre[1] - reach, centre[1] + reach)
        world_axes.set_zlim(0, max(2.0, high[2] + 0.3))
        world_axes.set_box_aspect((1, 1, max(2.0, high[2] + 0.3) / (2 * reach)))
        world_axes.set_title("world (m): prediction solid" + (", truth dashed" if target is not None else ""),
                             fontsize=9)
        fig.canvas.draw()
        images.append(Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()))
    plt.close(fig)
    return images


def save_animation(images: list[Image.Image], path: str | Path, fps: float, overwrite: bool = False) -> Path:
    """Write a GIF (Pillow) or, for .mp4, a video through ffmpeg (refused when no ffmpeg binary exists)."""
    path = Path(path)
    if path.suffix.lower() == ".gif":
        with atomic_path(path, overwrite) as temporary:
            images[0].save(temporary, format="GIF", save_all=True, append_images=images[1:],
                           duration=int(1000 / fps), loop=0)
        return path
    if path.suffix.lower() == ".mp4":
        if shutil.which("ffmpeg") is None:
            raise InputError(f"{path}: MP4 needs an ffmpeg binary on PATH; write a .gif instead")
        import matplotlib.animation as animation

        fig = plt.figure(figsize=(images[0].width / 100, images[0].height / 100), dpi=100)
        axes = fig.add_axes([0, 0, 1, 1])
        axes.axis("off")
        artist = axes.imshow(images[0])
        writer = animation.FFMpegWriter(fps=fps)
        with atomic_path(path, overwrite) as temporary, writer.saving(fig, str(temporary), dpi=100):
            for image in images:
                artist.set_data(image)
                writer.grab_frame()
        plt.close(fig)
        return path
    raise InputError(f"{path}: animations are .gif or .mp4")
