"""Lifting from files: the lifter a job chose (``chosen_lifter``) and a keypoint file lifted and written as
``ray3d lift`` does (``lift_file``)."""

from __future__ import annotations

from pathlib import Path

from ray3d.io.keypoints import Keypoints, read_keypoints
from ray3d.io.world import World
from ray3d.geometry import Camera
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions
from ray3d.models.precision import check_precision


def chosen_lifter(checkpoint: str | None = None, precision: str = "fp32", layout: str | None = None,
                  keypoints_path: str | Path | None = None) -> Lifter | None:
    """``checkpoint`` (or the shipped model for keypoints of ``layout``, else of the file ``keypoints_path``'s
    layout) in ``precision``; None when neither a checkpoint nor a reduced precision is asked for: then
    ``lift_file``, ``lift_video`` and ``run_live`` choose the shipped model for their input's layout themselves."""
    if not checkpoint and check_precision(precision) == "fp32":
        return None
    if not checkpoint and layout is None and keypoints_path is not None:
        layout = read_keypoints(keypoints_path).layout
    return Lifter.load(checkpoint, layout=layout or "h36m17", precision=precision)


def lift_file(keypoints_path: str | Path, camera: Camera, out: str | Path | None, lifter: Lifter | None = None,
              layout: str | None = None, fps: float | None = None, overwrite: bool = False,
              read_options: dict | None = None, options: LiftOptions = LiftOptions(),
              progress: bool = False) -> tuple[Keypoints, World]:
    """A keypoint file lifted into the world and written to ``out`` (.json/.csv/.npz/.trc/.bvh), as ``ray3d
    lift`` does, by ``lifter`` (default: the shipped model for the file's layout, ``Lifter.load(layout=...)``):
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
    world = (lifter or Lifter.load(layout=keypoints.layout)).lift_keypoints(keypoints, camera, options, progress)
    if out is not None:
        write_world(out, world, overwrite=overwrite)
    return keypoints, world
