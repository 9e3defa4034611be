"""Several cameras, one world (``ray3d.fusion``): ``ray3d fuse`` on world files, and ``ray3d lift`` with several
keypoint files, one per camera; ``ray3d video`` with several videos prints through ``print_fusion`` too."""

from __future__ import annotations

import argparse

from ray3d.io.atomic import check_output, refuse_existing


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
    from ray3d.cli.arguments import job_from_args
    from ray3d.errors import InputError
    from ray3d.cli.commands import print_ankle_plane
    from ray3d.jobs import fuse_and_write, lift_cameras_together

    job = job_from_args(args, args.keypoints, "keypoint files", "file")
    if args.out.suffix.lower() != ".json":
        raise InputError(f"{args.out}: several cameras' people are fused into a .json world file", ("out",))
    refuse_existing(check_output(args.out, (*args.keypoints, *(c.file for c in job.cameras))), args.force)
    worlds = []
    for k, (path, lifted) in enumerate(zip(job.inputs, lift_cameras_together(job))):
        print(f"{path}: {len(lifted.world.tracks)} track(s) through camera {lifted.camera.name or job.cameras[k].file}")
        worlds.append(lifted.world)
    print_ankle_plane(worlds[0].tracks)
    fusion = fuse_and_write(worlds, args.out, find_offsets=job.find_offsets, overwrite=args.force)
    print_fusion(fusion, [str(path) for path in args.keypoints])
    print(f"{len(fusion.world.tracks)} people from {len(worlds)} cameras -> {args.out}")
    return 0
