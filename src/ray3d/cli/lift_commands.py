"""``ray3d lift``: keypoint files and their cameras -> world 3D (one file, or several, one per camera, fused into one
world), and ``ray3d fuse``: several cameras' world files -> one world (``ray3d.fusion``)."""

from __future__ import annotations

import argparse
import sys

from ray3d.cli.arguments import add_out, job_from_args, parse_offsets
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


def add_parser(commands) -> None:
    """``ray3d lift`` and ``ray3d fuse``'s flags, each bound to its handler here."""
    from pathlib import Path

    from ray3d.cli.arguments import add_camera_arguments, add_force, add_lifting_arguments

    lift_parser = commands.add_parser("lift", help="2D keypoints + a calibrated camera -> 3D joints in world metres")
    lift_parser.add_argument("--keypoints", required=True, type=Path, action="append",
                      help="npz / JSON / CSV (ours), COCO results JSON, an OpenPose folder, or VideoPose3D "
                           "positions_2d npz; several, one per camera (each with its --camera): one fused world")
    add_camera_arguments(lift_parser, several=True)
    lift_parser.add_argument("--find-offsets", action="store_true",
                             help="several keypoint files: find how far apart their clocks are from the people both "
                                  "cameras see")
    add_out(lift_parser, "output .json, .csv or .npz (read back by ray3d viz), .trc (OpenSim / Pose2Sim markers) or "
                         ".bvh (a skeleton with joint rotations: Blender, Maya; one file per track)")
    lift_parser.add_argument("--layout",
                             help="joint layout of the keypoints (h36m17, coco17, halpe26, blazepose33, body25, ...)")
    lift_parser.add_argument("--fps", type=float, help="frame rate of the keypoints (default: from the file, else 60)")
    add_lifting_arguments(lift_parser)
    lift_parser.add_argument("--subject", help="VideoPose3D npz: the subject")
    lift_parser.add_argument("--action", help="VideoPose3D npz: the action")
    lift_parser.add_argument("--camera-index", type=int, help="VideoPose3D npz: the camera index (0-3)")
    add_force(lift_parser, "replace --out if it exists")
    lift_parser.set_defaults(handler=lift)

    fuse_parser = commands.add_parser("fuse",
                                      help="several cameras' world files (ray3d lift / video, one per camera) -> "
                                           "one world, one track per person, joints fused where cameras overlap")
    fuse_parser.add_argument("worlds", nargs="+", type=Path, help="world files (.json/.csv/.npz), one per camera; the "
                                                           "first sets the clock and frame numbers")
    add_out(fuse_parser, "the fused world file (.json)")
    fuse_parser.add_argument("--offsets", help="seconds each camera's clock is ahead of the first's, comma separated "
                                        "(the first 0; default all 0)")
    fuse_parser.add_argument("--find-offsets", action="store_true",
                             help="find the offsets from the people both cameras see at once")
    fuse_parser.add_argument("--max-offset", type=float, default=2.0,
                             help="the largest offset searched, seconds (default 2)")
    fuse_parser.add_argument("--handover", type=float, default=2.0,
                      help="a person leaving one view and entering another within this many seconds keeps their "
                           "track (default 2)")
    add_force(fuse_parser, "replace --out if it exists")
    fuse_parser.set_defaults(handler=fuse)
