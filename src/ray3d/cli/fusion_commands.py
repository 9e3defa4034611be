"""Several cameras, one world (``ray3d.fusion``): ``ray3d fuse`` on world files, and ``ray3d lift`` with several
keypoint files, one per camera; ``ray3d video`` with several videos prints through ``print_fusion`` too."""

from __future__ import annotations

import argparse

from ray3d.io.atomic import check_output, refuse_existing


def fuse(args: argparse.Namespace) -> int:
    """``ray3d fuse``: several cameras' world files -> one world, one track per person (``ray3d.fusion``)."""

    from ray3d.fusion import fuse_worlds
    from ray3d.io.world import read_world, write_world

    refuse_existing(check_output(args.out, tuple(args.worlds)), args.force)
    fusion = fuse_worlds([read_world(path) for path in args.worlds], parse_offsets(args.offsets), args.find_offsets,
                         args.max_offset, args.handover)
    write_world(args.out, fusion.world, overwrite=args.force)
    print_fusion(fusion, [str(path) for path in args.worlds])
    print(f"{len(fusion.world.tracks)} people from {len(args.worlds)} cameras -> {args.out}")
    return 0


def parse_offsets(text: str | None) -> list[float] | None:
    """``--offsets``: seconds separated by commas (None where not given)."""
    from ray3d.errors import InputError

    if not text:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--offsets: expected seconds separated by commas, got {text!r}") from None


def print_fusion(fusion, sources: list[str]) -> None:
    """The offsets, who joined whom, the cameras' agreement, and a warning on stderr naming a camera that
    disagrees."""
    import sys

    for source, offset, sd in zip(sources, fusion.offsets_s, fusion.offset_sd_s):
        print(f"{source}: offset {offset:+.3f} s" + (f" +- {sd:.3f} s (found)" if sd else ""))
    for track, members in fusion.members.items():
        print(f"  person {track}: {', '.join(members)}")
    for entry in fusion.agreement:
        print(f"  {entry['cameras'][0]} and {entry['cameras'][1]}: the same person {entry['median_distance_m']:.2f} m "
              f"apart, {entry['median_sigmas']:.1f} sd of their uncertainties (median of {entry['frames']} frames)")
    if fusion.suspects():
        print(f"warning: the cameras disagree on where people are beyond their uncertainties; check the calibration "
              f"of {' and '.join(fusion.suspects())}", file=sys.stderr)



def lift(args: argparse.Namespace) -> int:
    """``ray3d lift``: one keypoint file as always, several (one per camera) fused."""
    from ray3d.cli import commands

    if len(args.keypoints) > 1 or len(args.camera or []) > 1:
        return lift_several(args)
    return commands.lift(argparse.Namespace(**{**vars(args), "keypoints": args.keypoints[0],
                                               "camera": (args.camera or [None])[0]}))


def lift_several(args: argparse.Namespace) -> int:
    """``ray3d lift`` with several keypoint files, one per camera (``--camera`` once each, in order): each lifted
    as one camera's, then one fused world in --out (.json)."""
    from ray3d.cli.commands import _camera, _lift_options, cameras_per_input, with_camera
    from ray3d.errors import InputError
    from ray3d.fusion import fuse_worlds
    from ray3d.io.keypoints import read_keypoints
    from ray3d.io.world import write_world
    from ray3d.lifting.lifter import Lifter

    cameras = cameras_per_input(args, args.keypoints, "keypoint files", "file")
    if args.out.suffix.lower() != ".json":
        raise InputError(f"{args.out}: several cameras' people are fused into a .json world file", ("out",))
    refuse_existing(check_output(args.out, (*args.keypoints, *cameras)), args.force)
    lifter = Lifter.load(args.checkpoint, precision=args.precision) if args.checkpoint else None
    worlds = []
    for path, camera_file in zip(args.keypoints, cameras):
        one = with_camera(args, camera_file)
        keypoints = read_keypoints(path, args.layout, args.fps, subject=args.subject, action=args.action,
                                   camera_index=args.camera_index)
        world = (lifter or Lifter.load(layout=keypoints.layout, precision=args.precision)).lift_keypoints(keypoints, _camera(one),
                                                                                _lift_options(one))
        print(f"{path}: {len(world.tracks)} track(s) through camera {world.camera.name or camera_file}")
        worlds.append(world.in_frame("world"))
    fusion = fuse_worlds(worlds, find_offsets=args.find_offsets)
    write_world(args.out, fusion.world, overwrite=args.force)
    print_fusion(fusion, [str(path) for path in args.keypoints])
    print(f"{len(fusion.world.tracks)} people from {len(worlds)} cameras -> {args.out}")
    return 0
