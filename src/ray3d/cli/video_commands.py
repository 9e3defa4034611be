"""``ray3d video``: one video (or several, one per calibrated camera, fused into one world: ``ray3d.fusion``) ->
every person's track, world file, detections, viewer and overlay; with ``--site``, the site's report."""

from __future__ import annotations

import argparse
from pathlib import Path

from ray3d.cli.arguments import chosen_lifter
from ray3d.cli.commands import _camera, _lift_options, cameras_per_input, print_refinements, with_camera
from ray3d.errors import InputError


def video(args: argparse.Namespace) -> int:
    from ray3d.cli.site_commands import refuse_site_outputs, report_site
    from ray3d.io.site_files import read_site

    cameras = cameras_per_input(args, args.input, "videos", "video")
    plan = None
    if args.site is not None:  # refused before any work, not after it
        refuse_site_outputs(args.out / "site", (*args.input, args.site), args.force)
        plan = read_site(args.site)
    if len(args.input) == 1:
        result = _one_video(args, args.input[0], cameras[0], args.out)
        world, name = result.world, args.input[0].name
    else:
        world = _several_videos(args, cameras)
        name = f"{len(args.input)} cameras"
    if plan is not None:
        report_site(world, plan, args.out / "site", f"{name} on {args.site.name}", args.force)
    return 0


def _one_video(args: argparse.Namespace, video: Path, camera_file: str | None, out: Path):
    import numpy as np

    from ray3d.lifting.options import VideoOptions
    from ray3d.video import camera_for_video, lift_video, make_detector, read_video_info

    one = with_camera(args, camera_file)
    info = read_video_info(video)
    camera = camera_for_video(_camera(one, info.image_size), info)
    options = VideoOptions(args.fps, args.start, args.frames, args.max_gap, args.min_track)
    detector = make_detector(args.detector, camera)
    result = lift_video(info, camera, out, detector, chosen_lifter(args, detector.layout), _lift_options(one), options,
                        world_format=args.format, overlay=not (args.no_overlay or args.privacy), overwrite=args.force)
    tracks = result.world.tracks
    filled = np.mean([t.interpolated.all(axis=1).mean() for t in tracks.values()])
    print(f"{video}: {result.frames} frames, {len(tracks)} people tracked by the {args.detector} detector and "
          f"lifted by {result.world.model} ({len(result.dropped)} short or unliftable tracks dropped); "
          f"{100 * filled:.1f}% of their frames filled in between detections")
    seconds = result.seconds
    print(f"  {result.frames / sum(seconds.values()):.1f} frames/s end to end: people {seconds['people']:.1f} s, "
          f"lifting {seconds['lifting']:.1f} s, writing {seconds['writing']:.1f} s")
    print_refinements(tracks, camera)
    for role, path in result.files.items():
        print(f"  {role:<10}{path}")
    return result


def _several_videos(args: argparse.Namespace, cameras: list[str]):
    """Each video into OUT/camera<k>_<name>/ as one camera's, then the people fused into OUT/world.json and its
    viewer (``ray3d.fusion``; the videos taken to start together unless --find-offsets)."""
    from ray3d.cli.fusion_commands import print_fusion
    from ray3d.fusion import fuse_worlds
    from ray3d.io.atomic import refuse_existing
    from ray3d.io.world import write_world
    from ray3d.viz.html_viewer import write_viewer

    if args.format != ".json":
        raise InputError("--format: several cameras' people are fused into a .json world file", ("format",))
    fused_path, viewer_path = args.out / "world.json", args.out / "viewer.html"
    for path in (fused_path, viewer_path):
        refuse_existing(path, args.force)
    worlds = [_one_video(args, video, camera, args.out / f"camera{k + 1}_{video.stem}").world
              for k, (video, camera) in enumerate(zip(args.input, cameras))]
    fusion = fuse_worlds(worlds, find_offsets=args.find_offsets)
    write_world(fused_path, fusion.world, overwrite=args.force)
    write_viewer(viewer_path, fusion.world.tracks, fusion.world.fps, fusion.world.camera,
                 title=f"ray3d: {len(worlds)} cameras", overwrite=args.force, more_cameras=fusion.world.cameras[1:])
    print_fusion(fusion, [str(video) for video in args.input])
    print(f"{len(fusion.world.tracks)} people from {len(worlds)} cameras -> {fused_path}, {viewer_path}")
    return fusion.world
