"""The ``ray3d bench`` handlers: each parses nothing, calls one benchmark of ``ray3d.bench`` and prints where its
files went."""

from __future__ import annotations

import argparse

from ray3d.cli.commands import write_json
from ray3d.errors import InputError


def robustness(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.bench.robustness import run, write
    from ray3d.data import motion as motion_data

    clips = motion_data.load_shipped(args.data_dir, "test")
    if args.clips:
        clips = clips.select(np.arange(clips.num_clips) < args.clips)
    sweeps = run(args.models, clips, args.frame_stride, args.camera_stride)
    files = write(sweeps, args.out)
    print(f"{len(sweeps)} sweeps x {len(args.models)} methods on {clips.num_clips} test clips -> {len(files)} files "
          f"in {args.out} (see {args.out / 'summary.md'})")
    return 0


def calibration(args: argparse.Namespace) -> int:
    from ray3d.bench.calibration import run, write
    from ray3d.data import motion as motion_data
    from ray3d.lift import Lifter

    if args.people < 1:
        raise InputError(f"bench calibration: people must be at least 1, got {args.people}", arguments=("people",))
    rows = run(motion_data.load_shipped(args.data_dir, args.split), Lifter.load(args.checkpoint), args.pairs, args.seed,
               args.bootstrap, people=args.people)
    files = write(rows, args.out)
    print((args.out / "calibration.md").read_text())
    print(f"{len(rows)} estimates -> {', '.join(map(str, files))}")
    return 0


def real_video(args: argparse.Namespace) -> int:
    from ray3d.bench.real_video import run_emulated, run_video, write
    from ray3d.data import motion as motion_data
    from ray3d.io.camera_files import read_camera
    from ray3d.io.keypoints import read_keypoints
    from ray3d.lift import Lifter

    lifter, video_rows, name = Lifter.load(args.checkpoint), None, ""
    if args.video or args.keypoints:
        if not args.camera:
            raise InputError("bench real-video: --video and --keypoints need --camera")
        if args.keypoints:
            keypoints, name = read_keypoints(args.keypoints, fps=args.fps), args.keypoints.name
        else:
            from ray3d.video import make_detector, track_video

            camera = read_camera(args.camera)
            keypoints = track_video(args.video, camera, make_detector(args.detector, camera), args.fps)[0]
            name = args.video.name
        video_rows = run_video(lifter, keypoints, read_camera(args.camera), args.smooth_3d)
    emulated = run_emulated(lifter, motion_data.load_shipped(args.data_dir, "test"), args.pairs, args.seed,
                            smooth_3d=args.smooth_3d)
    files = write(args.out, emulated, video_rows, name)
    print(files[1].read_text())
    print(f"-> {', '.join(map(str, files))}")
    return 0


def speed(args: argparse.Namespace) -> int:
    from ray3d.bench.speed import measure_all

    result = measure_all(args.models, args.repeats, batch_size=args.batch, sequence_frames=args.sequence_frames,
                         train_batch=args.train_batch)
    by_path = ", ".join(f"{name.removesuffix('_gflops')} {rate:.0f}"
                        for name, rate in result["matmul_paths_gflops"].items())
    print(f"fp32 matmul peak: {result['matmul_peak_gflops']:.0f} GFLOP/s ({by_path}); torch threads "
          f"{result['torch_threads']}")
    print(f"{'model':<15}{'backend':<13}{'params':>12}{'MFLOP/f':>9}{'batch f/s':>11}{'seq f/s':>10}"
          f"{'latency ms':>11}{'stream ms':>10}{'train s/s':>10}{'% peak':>8}")
    for r in result["models"]:
        train_rate = f"{r['train_samples_per_s']:>10,.0f}" if r["train_samples_per_s"] else f"{'-':>10}"
        print(f"{r['model']:<15}{r['backend']:<13}{r['params']:>12,}{r['mflops_per_frame']:>9.2f}"
              f"{r['batch_frames_per_s']:>11,.0f}{r['sequence_frames_per_s']:>10,.0f}{r['latency_ms']:>11.2f}"
              f"{r['stream_ms_per_frame']:>10.2f}{train_rate}{100 * r['fraction_of_peak']:>8.1f}")
    if args.json:
        write_json(args.json, result, args.force)
    return 0
