"""``ray3d video``: one video (or several, one per calibrated camera, fused into one world: ``ray3d.fusion``) ->
every person's track, world file, detections, viewer and overlay; with ``--site``, the site's report."""

from __future__ import annotations

import argparse

from ray3d.cli.arguments import job_from_args
from ray3d.cli.commands import print_refinements
from ray3d.errors import InputError


def video(args: argparse.Namespace) -> int:
    from ray3d.cli.fusion_commands import print_fusion
    from ray3d.cli.site_commands import refuse_site_outputs, report_site
    from ray3d.io.atomic import refuse_existing
    from ray3d.site.files import read_site
    from ray3d.jobs import fuse_and_write, run_input, run_videos_together

    job = job_from_args(args, args.input, "videos", "video")
    several = len(job.inputs) > 1
    plan = None
    if args.site is not None:  # refused before any work, not after it
        refuse_site_outputs(args.out / "site", (*args.input, args.site), args.force, args.every)
        plan = read_site(args.site)
    fused_path, viewer_path = args.out / "world.json", args.out / "viewer.html"
    if several:
        if args.format != ".json":
            raise InputError("--format: several cameras' people are fused into a .json world file", ("format",))
        for path in (fused_path, viewer_path):
            refuse_existing(path, args.force)
    # Several cameras of one site are lifted together, on one floor.
    results = run_videos_together(job, [args.out / f"camera{k + 1}_{path.stem}" for k, path in enumerate(job.inputs)]) \
        if several else [run_input(job, 0, args.out)]
    worlds = []
    for path, result in zip(job.inputs, results):
        _print_video(path, args.detector, result)
        worlds.append(result.world)
    if several:
        fusion = fuse_and_write(worlds, fused_path, find_offsets=job.find_offsets, viewer_path=viewer_path,
                                overwrite=args.force)
        print_fusion(fusion, [str(path) for path in job.inputs])
        print(f"{len(fusion.world.tracks)} people from {len(worlds)} cameras -> {fused_path}, {viewer_path}")
        world, name = fusion.world, f"{len(job.inputs)} cameras"
    else:
        world, name = worlds[0], args.input[0].name
    if plan is not None:
        report_site(world, plan, args.out / "site", f"{name} on {args.site.name}", args.force, args.every,
                    args.start_time)
    return 0


def _print_video(video, detector: str, result) -> None:
    import numpy as np

    lifted = result.video
    tracks = result.world.tracks
    filled = np.mean([t.interpolated.all(axis=1).mean() for t in tracks.values()])
    rejoins = sum(len(r) for r in result.world.rejoined.values())
    cut = result.world.in_part
    print(f"{video}: {result.frames} frames, {len(tracks)} people tracked by the {detector} detector and "
          f"lifted by {result.world.model} ({len(lifted.dropped)} short or unliftable tracks dropped, {rejoins} "
          f"taken up again after a gap); {100 * filled:.1f}% of their frames filled in between detections")
    if cut:
        print(f"  {len(cut)} people cut by the picture's edge in {sum(map(len, cut.values()))} of their frames "
              f"(the world file's in_part)")
    seconds = lifted.seconds
    print(f"  {result.frames / sum(seconds.values()):.1f} frames/s end to end: people {seconds['people']:.1f} s, "
          f"lifting {seconds['lifting']:.1f} s, writing {seconds['writing']:.1f} s")
    print_refinements(tracks, result.camera)
    for role, path in result.files.items():
        print(f"  {role:<10}{path}")
