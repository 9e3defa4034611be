"""``ray3d data``: what motion data is available, importers (BVH, ASF/AMC), virtual camera sets, the
training-sample generator's speed."""

from __future__ import annotations

import argparse
from pathlib import Path


def data_info(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.virtual_cameras import SET_NAMES, grid

    data_dir = motion.resolve_data_dir(args.data_dir)
    info = motion.summary(motion.load_shipped(data_dir))
    print(f"motion data: {data_dir}")
    print(f"  {info['clips']} clips, {info['frames']:,} frames, {info['minutes']:.1f} minutes (H36M-17, 60 fps)")
    for title, key in (("split (by performer)", "splits"), ("performer", "performers"), ("body", "bodies")):
        print(f"\n  {title:<22}{'clips':>7}{'frames':>10}{'minutes':>9}")
        for name, row in sorted(info[key].items()):
            print(f"  {name:<22}{row['clips']:>7}{row['frames']:>10,}{row['minutes']:>9.1f}")
    print("\n  test performers: " + ", ".join(motion.SPLITS["test"]) + "; validation: "
          + ", ".join(motion.SPLITS["validation"]))
    print("\ncamera sets (before the in-image filter): "
          + ", ".join(f"{name} {len(grid(name))}" for name in SET_NAMES))
    return 0


def _write_imported(args: argparse.Namespace, clips, files: list[Path], source: str) -> int:
    from ray3d.data.importers import clips_to_motion_set

    motion = clips_to_motion_set(clips, [f.stem for f in files], args.subject, source)
    motion.save(args.out, overwrite=args.force)
    minutes = motion.num_frames / args.fps / 60
    print(f"wrote {args.out}: {motion.num_clips} clip(s), {motion.num_frames} frames ({minutes:.2f} min) at "
          f"{args.fps:g} fps; floor offsets {', '.join(f'{c.floor_offset_m:+.3f}' for c in clips)} m")
    return 0


def import_bvh(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_bvh as read

    clips = [read(f, args.fps, args.drop_frames, not args.no_floor, args.units) for f in args.files]
    return _write_imported(args, clips, args.files, "user_bvh")


def import_amc(args: argparse.Namespace) -> int:
    from ray3d.data.importers import import_amc as read

    clips = [read(args.asf, f, args.fps, args.native_fps, args.drop_frames, not args.no_floor) for f in args.amc]
    return _write_imported(args, clips, args.amc, "user_amc")


def cameras(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.virtual_cameras import cameras_seeing, grid
    from ray3d.io.camera_files import save_cameras

    if args.no_filter:
        cams, note = grid(args.set), "not filtered"
    else:
        clips = motion.load_shipped(args.data_dir, args.split)
        cams = cameras_seeing(args.set, clips)
        note = f"kept cameras that see every joint of all {clips.num_clips} {args.split} clips (centred)"
    save_cameras(args.out, cams, overwrite=args.force, set=args.set, filter=note)
    print(f"wrote {args.out}: {len(cams)} of {len(grid(args.set))} '{args.set}' cameras ({note})")
    return 0


def samples_speed(args: argparse.Namespace) -> int:
    from ray3d.data import motion
    from ray3d.data.samples import THROUGHPUT_CASES, measure_throughput
    from ray3d.temporal import Window

    train = motion.load_shipped(args.data_dir, "train")
    print(f"training-sample generator: batch {args.batch} windows of {args.frames} frames, median of {args.repeats}")
    for name, config in THROUGHPUT_CASES.items():
        result = measure_throughput(train, config, Window(args.frames), args.batch, args.repeats)
        print(f"  {name:<36}{result['ms_per_batch']:8.1f} ms/batch{result['samples_per_s']:10,.0f} samples/s")
    return 0
