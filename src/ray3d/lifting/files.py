"""Lifting from files: a keypoint file lifted and written as ``ray3d lift`` does (``lift_file``)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ray3d.geometry import Camera
from ray3d.io.keypoints import Keypoints, read_keypoints
from ray3d.io.world import World
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions


def lift_file(keypoints_path: str | Path, camera: Camera, out: str | Path | None,
              lifter: Lifter | Callable[[str], Lifter] | None = None,
              layout: str | None = None, fps: float | None = None, overwrite: bool = False,
              read_options: dict | None = None, options: LiftOptions = LiftOptions(),
              progress: bool = False) -> tuple[Keypoints, World]:
    """A keypoint file lifted into the world and written to ``out`` (.json/.csv/.npz/.trc/.bvh), as ``ray3d
    lift`` does, by ``lifter`` (or the one a function of the file's layout gives, as ``jobs.Job.lifter`` does;
    default: the shipped model for the file's layout, ``Lifter.load(layout=...)``):
    ``layout`` and ``fps`` as the file states them unless given, ``read_options`` for the reader
    (``subject``, ``action``, ``camera_index`` of a VideoPose3D npz), ``options`` for the lifting (the output
    smoothed by Savitzky-Golay and written in the world frame unless they say otherwise). Returns what was read
    and what was written (``out`` None: lifted, not written)."""
    from ray3d.io.atomic import check_output, refuse_existing
    from ray3d.io.world import check_world_output, write_world

    if out is not None:
        check_output(out, (keypoints_path,))
        check_world_output(out, options.frame)
        refuse_existing(out, overwrite)
    keypoints = read_keypoints(keypoints_path, layout, fps, **(read_options or {}))
    if not isinstance(lifter, Lifter):
        lifter = lifter(keypoints.layout) if lifter else Lifter.load(layout=keypoints.layout)
    world = lifter.lift_keypoints(keypoints, camera, options, progress)
    if out is not None:
        write_world(out, world, overwrite=overwrite)
    return keypoints, world
