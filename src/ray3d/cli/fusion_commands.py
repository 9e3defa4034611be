"""Several cameras, one world (``ray3d.fusion``): ``ray3d fuse`` on world files, and ``ray3d lift`` with several
keypoint files, one per camera; ``ray3d video`` with several videos prints through ``print_fusion`` too."""

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
    """``ray3d lift``: one keypoint file as always, several (one per camera) fused."""


    if len(args.keypoints) > 1 or len(args.camera or []) > 1:
        return lift_several(args)
    return lift_one(argparse.Namespace(**{**vars(args), "keypoints": args.keypoints[0],
                                               "camera": (args.camera or [None])[0]}))


def lift_one(args: argparse.Namespace) -> int:
    """``ray3d lift`` of one keypoint file and its camera."""
    from ray3d.console import showing_progress
    from ray3d.jobs import run_job

    check_output(args.out, (args.camera,))
    done = run_job(job_from_args(args, [args.keypoints], "keypoint files", "file"), args.out,
                   progress=showing_progress())
    print_notes(done.notes)
    lifted = done.inputs[0]
    keypoints, world, camera = lifted.keypoints, lifted.world, lifted.camera
    if keypoints.fps is None:
        print(f"note: {args.keypoints} states no frame rate: assumed the models' 60 fps (pass --fps if it is "
              "another; speeds and smoothing depend on it)", file=sys.stderr)
    print_keypoint_notes(args.keypoints, keypoints)
    frames = sum(len(r.joints) for r in world.tracks.values())
    filled = sum(int(r.interpolated.sum()) for r in world.tracks.values())
    written = ", ".join(str(p) for p in lifted.files.values())
    print(f"lifted {len(world.tracks)} track(s), {frames} frames ({keypoints.layout}, {keypoints.source}) with "
          f"{world.model} through camera {camera.name or args.camera} -> {written} (metres, {args.frame} frame)")
    if filled:
        print(f"note: {filled} missing input joint(s) were interpolated in time (listed in the output)")
    for track, why in world.unliftable.items():
        print(f"warning: track {track} was not lifted: {why}", file=sys.stderr)
    print_refinements(world.tracks, camera)
    return 0


def lift_several(args: argparse.Namespace) -> int:
    """``ray3d lift`` with several keypoint files, one per camera (``--camera`` once each, in order): each lifted
    as one camera's, then one fused world in --out (.json)."""
    from ray3d.console import showing_progress
    from ray3d.jobs import run_job

    job = job_from_args(args, args.keypoints, "keypoint files", "file")
    done = run_job(job, args.out, progress=showing_progress())
    print_notes(done.notes)
    for path, lifted, choice in zip(job.inputs, done.inputs, job.cameras):
        print_keypoint_notes(path, lifted.keypoints)
        print(f"{path}: {len(lifted.world.tracks)} track(s) through camera {lifted.camera.name or choice.file}")
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
    lift_parser.add_argument("--out", required=True, type=Path,
                      help="output .json, .csv or .npz (read back by ray3d viz), .trc (OpenSim / Pose2Sim markers) or "
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
    fuse_parser.add_argument("--out", required=True, type=Path, help="the fused world file (.json)")
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
