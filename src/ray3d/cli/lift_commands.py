"""``ray3d lift``: keypoint files and their cameras -> world 3D (one file, or several, one per camera, fused into one
world), and ``ray3d fuse``: several cameras' world files -> one world (``ray3d.fusion``)."""

from __future__ import annotations

import argparse
import sys

from ray3d.cli.arguments import job_from_args, parse_offsets
from ray3d.cli.printing import print_ankle_plane, print_fusion, print_keypoint_notes, print_notes, print_refinements
from ray3d.io.atomic import check_output


def fuse(args: argparse.Namespace) -> int:
    """``ray3d fuse``: several cameras' world files -> one world, one track per person (``ray3d.fusion``)."""

    from ray3d.io.world import read_world
    from ray3d.jobs import fuse_and_write

    check_output(args.out, tuple(args.worlds))
    fusion = fuse_and_write([read_world(path) for path in args.worlds], args.out, parse_offsets(args.offsets),
                            args.find_offsets, args.max_offset, args.handover, overwrite=args.force)
    print_fusion(fusion, [str(path) for path in args.worlds])
    print(f"{len(fusion.world.tracks)} people from {len(args.worlds)} cameras -> {args.out}")
    return 0


def lift(args: argparse.Namespace) -> int:
    """``ray3d lift``: each keypoint file through its camera (``--camera`` once each, in order); several, one per
    camera, fused into one world in --out."""
    from ray3d.console import showing_progress
    from ray3d.jobs import run_job

    check_output(args.out, (*args.keypoints, *(args.camera or [])))
    job = job_from_args(args, args.keypoints, "keypoint files", "file")
    done = run_job(job, args.out, progress=showing_progress())
    print_notes(done.notes)
    for path, lifted, choice in zip(job.inputs, done.inputs, job.cameras):
        keypoints, world, camera = lifted.keypoints, lifted.world, lifted.camera
        if keypoints.fps is None and args.fps is None:
            print(f"note: {path} states no frame rate: assumed the models' 60 fps (pass --fps if it is another; "
                  "speeds and smoothing depend on it)", file=sys.stderr)
        print_keypoint_notes(path, keypoints)
        frames = sum(len(r.joints) for r in world.tracks.values())
        filled = sum(int(r.interpolated.sum()) for r in world.tracks.values())
        written = ", ".join(str(p) for p in lifted.files.values())
        print(f"{path}: lifted {len(world.tracks)} track(s), {frames} frames ({keypoints.layout}, {keypoints.source}) "
              f"with {world.model} through camera {camera.name or choice.file}" +
              (f" -> {written} (metres, {args.frame} frame)" if written else ""))
        if filled:
            print(f"note: {filled} missing input joint(s) were interpolated in time (listed in the output)")
        for track, why in world.unliftable.items():
            print(f"warning: track {track} was not lifted: {why}", file=sys.stderr)
        if done.fusion is None:
            print_refinements(world.tracks, camera)
    if done.fusion is not None:
        print_ankle_plane(done.inputs[0].world.tracks)
        print_fusion(done.fusion, [str(path) for path in args.keypoints])
        print(f"{len(done.world.tracks)} people from {len(job.inputs)} cameras -> {args.out}")
    return 0
