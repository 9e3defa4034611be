"""The camera's view beside the 3D world view and the floor plan, frame by frame: ground grid, camera frustum,
everybody's path; ground truth dashed, prediction solid; one person's left in blue and right in red (as the
paper's figures), several people each in their own colour with their id.
GIF through Pillow, MP4 through OpenCV (frame by frame, bounded memory; no ffmpeg needed)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from PIL import GifImagePlugin, Image  # noqa: E402

from ray3d.errors import InputError  # noqa: E402
from ray3d.geometry import Camera  # noqa: E402
from ray3d.io.atomic import atomic_path  # noqa: E402
from ray3d.io.world import LiftResult  # noqa: E402
from ray3d.skeleton import H36M17  # noqa: E402

LEFT, RIGHT, CENTRE = "#1f5fd6", "#d62f2f", "#444444"
PALETTE = ("#d62f2f", "#1f5fd6", "#2a9d3c", "#9c27b0", "#ef8a00", "#00a0a0", "#7a4a00", "#c800c8")


def as_track(sequence: np.ndarray | LiftResult) -> tuple[int, np.ndarray, np.ndarray]:
    """(first frame, joints (T, 17, 3), filled in (T,)) of an array from frame 0 or a lifted track."""
    if isinstance(sequence, LiftResult):
        return int(sequence.frames[0]), sequence.joints, sequence.interpolated.all(axis=1)
    joints = np.asarray(sequence, dtype=np.float64)
    return 0, joints, np.zeros(len(joints), dtype=bool)


def bone_colour(child: int) -> str:
    name = H36M17.joint_names[child]
    return LEFT if name.startswith("l_") else RIGHT if name.startswith("r_") else CENTRE


def frustum_lines(camera: Camera, depth: float = 0.6) -> list[np.ndarray]:
    """World line segments (2, 3) drawing the camera as a small pyramid pointing where it looks."""
    width, height = camera.image_size
    corners_px = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=float)
    corners = camera.camera_to_world(depth * camera.pixels_to_camera_rays(corners_px))
    centre = camera.center
    return [np.stack([centre, c]) for c in corners] + [np.stack([corners[i], corners[(i + 1) % 4]]) for i in range(4)]


def frame_span(sequences: dict[str, np.ndarray | LiftResult]) -> tuple[int, int]:
    """(first, last) frame over all ``sequences`` (arrays start at frame 0, tracks at their own frame)."""
    tracks = [as_track(s) for s in sequences.values()]
    return min(start for start, _, _ in tracks), max(start + len(joints) - 1 for start, joints, _ in tracks)


def render_frames(sequences: dict[str, np.ndarray | LiftResult], camera: Camera, pixels: dict | None = None,
                  target: np.ndarray | None = None, stride: int = 1, size_px: int = 720,
                  fps: float | None = None) -> Iterator[Image.Image]:
    """One image per ``stride``-th frame, made as it is asked for (a long clip is never all in memory): the
    camera's view, the world, and the floor plan with everybody's path.

    ``sequences`` are {name: world joints (T, 17, 3) from frame 0, or a ``LiftResult`` (a track: it starts at its
    own frame)}; one sequence is drawn left blue / right red, several each in its own colour with its name.
    The camera's view shows the world joints projected back through ``camera`` (thick) over the 2D input
    ``pixels`` ({name: (T, 17, 2)} H36M-17 pixels, one row per row of the sequence; thin, dotted; optional);
    ``target`` (T, 17, 3) is ground truth, dashed, for the first sequence; ``fps`` puts the time in the title.
    The figure and its lines are made once and moved frame by frame (making them anew cost most of the time).
    """
    tracks = {str(name): as_track(s) for name, s in sequences.items()}
    first, last = frame_span(sequences)
    shown = {name: camera.project(joints) for name, (_, joints, _) in tracks.items()}
    inputs = {str(name): np.asarray(p, dtype=np.float64) for name, p in (pixels or {}).items()}
    everything = np.concatenate([j.reshape(-1, 3) for _, j, _ in tracks.values()] + [camera.center[None]]
                                + ([target.reshape(-1, 3)] if target is not None else []))
    everything = everything[np.isfinite(everything).all(-1)]
    people = np.concatenate([j[:, 0, :2] for _, j, _ in tracks.values()])
    centre = np.median(people, axis=0)
    reach = max(1.5, np.percentile(np.abs(people - centre), 98) + 0.8)
    colours = {name: PALETTE[i % len(PALETTE)] for i, name in enumerate(tracks)}
    bones = [(child, parent) for child, parent in enumerate(H36M17.parents) if parent >= 0]
    single = len(tracks) == 1
    fig = plt.figure(figsize=(size_px * 3 / 200, size_px / 200), dpi=100)  # three square-ish panels in a row
    image_axes, world_axes = fig.add_subplot(1, 3, 1), fig.add_subplot(1, 3, 2, projection="3d")
    plan_axes = fig.add_subplot(1, 3, 3)
    top = max(2.0, float(np.percentile(everything[:, 2], 99)) + 0.3)
    width, height = camera.image_size

    # What every frame shares: the ground grid, the camera, everybody's whole path on the floor plan.
    grid = np.arange(np.floor(centre[0] - reach), np.ceil(centre[0] + reach) + 0.01, 0.5)
    grid_y = np.arange(np.floor(centre[1] - reach), np.ceil(centre[1] + reach) + 0.01, 0.5)
    for x in grid:
        world_axes.plot([x, x], [grid_y[0], grid_y[-1]], [0, 0], color="#dddddd", lw=0.5)
    for y in grid_y:
        world_axes.plot([grid[0], grid[-1]], [y, y], [0, 0], color="#dddddd", lw=0.5)
    for line in frustum_lines(camera):
        world_axes.plot(*line.T, color="#888888", lw=0.8)
    plan_axes.plot(*camera.center[:2], "ks", ms=5)
    lines = {}  # name -> the artists that move with that sequence
    for name, (_, joints, _) in tracks.items():
        colour = colours[name]
        plan_axes.plot(*joints[:, 0, :2].T, color=colour, lw=0.8, alpha=0.4)
        drawn = {"image": [image_axes.plot([], [], lw=1.5)[0] for _ in bones],
                 "world": [world_axes.plot([], [], [], "-", lw=2)[0] for _ in bones],
                 "path": world_axes.plot([], [], [], color="#2a9d3c" if single else colour, lw=1)[0],
                 "plan": plan_axes.plot([], [], "o", color=colour, ms=5)[0]}
        if name in inputs:
            drawn["input"] = [image_axes.plot([], [], ":", lw=1)[0] for _ in bones]
        if target is not None and name == next(iter(tracks)):
            drawn["truth"] = [world_axes.plot([], [], [], "--", lw=2)[0] for _ in bones]
        if not single:
            drawn["labels"] = [world_axes.text(0, 0, 0, name, color=colour, fontsize=7),
                               plan_axes.annotate(name, (0, 0), xytext=(4, 4), textcoords="offset points",
                                                  color=colour, fontsize=7),
                               image_axes.annotate(name, (0, 0), xytext=(3, 6), textcoords="offset points",
                                                   color=colour, fontsize=7)]
        drawn["every"] = [a for group in drawn.values() for a in (group if isinstance(group, list) else [group])]
        lines[name] = drawn
    image_axes.set(xlim=(0, width), ylim=(height, 0), aspect="equal", xlabel="u (px)", ylabel="v (px)")
    legend = [Line2D([], [], color="#444444", lw=1.5, label="lifted joints, projected")]
    if inputs:
        legend.append(Line2D([], [], color="#444444", lw=1, ls=":", label="input keypoints"))
    image_axes.legend(handles=legend, loc="lower right", fontsize=7, frameon=False)
    world_axes.set(xlim=(centre[0] - reach, centre[0] + reach), ylim=(centre[1] - reach, centre[1] + reach),
                   zlim=(0, top), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    world_axes.set_box_aspect((1, 1, max(0.3, top / (2 * reach))))  # a wide scene keeps some height
    world_axes.set_zticks(np.arange(0.0, top + 1e-9, 1.0))
    world_axes.set_title("world (m)" + (": prediction solid, truth dashed" if target is not None else ""),
                         fontsize=9)
    plan_axes.set(aspect="equal", xlabel="x (m)", ylabel="y (m)")
    plan_axes.set_title("floor plan: paths, camera (square)", fontsize=9)
    title = image_axes.set_title("", fontsize=9)

    for t in range(first, last + 1, stride):
        title.set_text(f"camera view (frame {t}, {t / fps:.2f} s)" if fps else f"camera view (frame {t})")
        for name, (start, joints, filled) in tracks.items():
            row, drawn = t - start, lines[name]
            visible = 0 <= row < len(joints)
            for artist in drawn["every"]:
                artist.set_visible(visible)
            if not visible:
                continue
            grey = filled[row]
            for k, (child, parent) in enumerate(bones):
                colour = "#aaaaaa" if grey else bone_colour(child) if single else colours[name]
                ends = [child, parent]
                drawn["image"][k].set_data(*shown[name][row, ends].T)
                drawn["image"][k].set_color(colour)
                drawn["world"][k].set_data_3d(*joints[row, ends].T)
                drawn["world"][k].set_color(colour)
                if "input" in drawn:
                    given = inputs[name]
                    drawn["input"][k].set_visible(row < len(given))
                    if row < len(given):
                        drawn["input"][k].set_data(*given[row, ends].T)
                        drawn["input"][k].set_color(colour)
                if "truth" in drawn:
                    drawn["truth"][k].set_data_3d(*target[row, ends].T)
                    drawn["truth"][k].set_color(colour)
            drawn["path"].set_data_3d(joints[: row + 1, 0, 0], joints[: row + 1, 0, 1], np.zeros(row + 1))
            drawn["plan"].set_data([joints[row, 0, 0]], [joints[row, 0, 1]])
            if "labels" in drawn:
                in_world, on_plan, in_image = drawn["labels"]
                in_world.set_position_3d(joints[row, 10] + [0, 0, 0.15])
                on_plan.xy = tuple(joints[row, 0, :2])
                head = shown[name][row, 10]
                in_image.set_visible(bool(np.isfinite(head).all()))
                if np.isfinite(head).all():
                    in_image.xy = tuple(head)
        if t == first:  # the panels' layout once: it is the same for every frame, and costs more than drawing
            fig.tight_layout()
        fig.canvas.draw()
        yield Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
    plt.close(fig)


def _write_gif(images: Iterable[Image.Image], handle, fps: float) -> None:
    """A looping GIF written as the images come (Pillow's frame encoder; ``Image.save(save_all=True)`` would hold
    every frame): the first frame's palette is the file's, every frame also carries its own."""
    duration = int(round(1000 / fps))
    count = 0
    for image in images:
        frame = image.convert("P", palette=Image.Palette.ADAPTIVE)
        if count == 0:
            header, _ = GifImagePlugin.getheader(frame, info={"loop": 0, "duration": duration})
            handle.write(b"".join(header))
        for chunk in GifImagePlugin.getdata(frame, duration=duration, include_color_table=True):
            handle.write(chunk)
        count += 1
    if count == 0:
        raise InputError("animation: no frames to write")
    handle.write(b";")  # the GIF trailer


def check_animation_path(path: str | Path) -> str:
    """The animation format ``path`` names by its suffix, ".gif" or ".mp4"; anything else is refused."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise InputError(f"{path}: animations are .gif or .mp4", arguments=("animation",))
    return suffix


def save_animation(images: Iterable[Image.Image], path: str | Path, fps: float, overwrite: bool = False) -> Path:
    """Write the images as a GIF (Pillow) or an MP4 (OpenCV), frame by frame as they come: any length in
    bounded memory."""
    path = Path(path)
    suffix = check_animation_path(path)
    with atomic_path(path, overwrite) as temporary:
        if suffix == ".gif":
            with temporary.open("wb") as handle:
                _write_gif(images, handle, fps)
            return path
        writer = None
        try:
            for image in images:
                if writer is None:
                    writer = cv2.VideoWriter(str(temporary), cv2.VideoWriter_fourcc(*"mp4v"), fps, image.size)
                    if not writer.isOpened():
                        raise InputError(f"{path}: OpenCV cannot write MP4 video here")
                writer.write(cv2.cvtColor(np.asarray(image), cv2.COLOR_RGB2BGR))
        finally:
            if writer is not None:
                writer.release()
    return path
