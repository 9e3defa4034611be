"""``ray3d video``: one video (or several, one per calibrated camera, fused into one world: ``ray3d.fusion``) ->
every person's track, world file, detections, viewer and overlay; with ``--site``, the site's report."""

from __future__ import annotations

import argparse

from ray3d.cli.arguments import job_from_args
from ray3d.cli.printing import print_notes, print_refinements


def video(args: argparse.Namespace) -> int:
    from ray3d.cli.printing import known_cameras, print_fusion, print_site_doubts, print_site_report
    from ray3d.console import showing_progress
    from ray3d.jobs import run_job

    job = job_from_args(args, args.input, "videos", "video")
    said = frozenset()
    if job.site is not None:  # a site drawn in pixels, said before the videos are read
        plan = job.site_plan()
        said = print_site_doubts(job.site, plan, known_cameras(job))
    done = run_job(job, args.out, progress=showing_progress())
    print_notes(done.notes)
    for path, result in zip(job.inputs, done.inputs):
        _print_video(path, args.detector, result)
    if done.fusion is not None:
        print_fusion(done.fusion, [str(path) for path in job.inputs])
        print(f"{len(done.world.tracks)} people from {len(job.inputs)} cameras -> {done.files['world']}, "
              f"{done.files['viewer']}")
    if done.site is not None:
        print_site_doubts(job.site, plan, done.world.cameras, done.world, said)  # and where nobody went
        print_site_report(done.site, done.world)
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
