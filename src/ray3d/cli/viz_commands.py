"""``ray3d viz``: an HTML viewer and a GIF / MP4 of world files (``ray3d.viz``)."""

from __future__ import annotations

import argparse

from ray3d.cli.printing import print_keypoint_notes
from ray3d.errors import InputError
from ray3d.io.atomic import check_output


def viz(args: argparse.Namespace) -> int:
    from ray3d.console import progress_bar
    from ray3d.io.camera_files import read_camera
    from ray3d.io.world import read_world
    from ray3d.temporal import check_frame_rate
    from ray3d.viz.animation import check_animation_path, frame_span, render_frames, save_animation
    from ray3d.viz.html_viewer import write_viewer

    if not args.html and not args.animation:
        raise InputError("viz: nothing to write: pass --html and/or --animation")
    for target in (args.html, args.animation):
        if target is not None:
            check_output(target, (*args.world, args.camera, args.keypoints))
    if args.animation is not None:
        check_animation_path(args.animation)
    worlds = [read_world(path).in_frame("world") for path in args.world]  # a camera-frame file too
    sequences = {}
    for path, world in zip(args.world, worlds):
        chosen = [args.track] if args.track is not None else list(world.tracks)
        for track in chosen:  # every track of every file; a file's stem names it when there are several files
            result = world.track(track)
            sequences[track if len(worlds) == 1 else f"{path.stem}:{track}"] = result
    fps = check_frame_rate(worlds[0].fps if args.fps is None else args.fps, "viz")
    camera = read_camera(args.camera) if args.camera else worlds[0].camera
    if args.html:
        write_viewer(args.html, sequences, fps, camera, overwrite=args.force,
                     more_cameras=() if args.camera else worlds[0].cameras[1:])
        print(f"wrote {args.html} ({len(sequences)} tracks, {fps:g} frames/s)")
    if args.animation:
        if args.stride < 1:
            raise InputError(f"viz: stride must be 1 or more, got {args.stride}", arguments=("stride",))
        inputs = None
        if args.keypoints is not None:
            from ray3d.io.keypoints import read_keypoints

            keypoints = read_keypoints(args.keypoints)
            inputs = {name: keypoints.h36m_pixels(name.split(":")[-1], result.frames)
                      for name, result in sequences.items()}
        first, last = frame_span(sequences)
        images = progress_bar(render_frames(sequences, camera, inputs, stride=args.stride, fps=fps), desc="rendering",
                              unit="frame", total=(last - first) // args.stride + 1, leave=False)
        save_animation(images, args.animation, fps / args.stride, overwrite=args.force)
        print(f"wrote {args.animation}")
        if args.keypoints is not None:
            print_keypoint_notes(args.keypoints, keypoints)
    return 0
