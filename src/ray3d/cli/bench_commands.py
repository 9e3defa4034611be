"""The ``ray3d bench`` handlers: each parses nothing, calls one benchmark of ``ray3d.bench`` and prints where its
files went."""

from __future__ import annotations

import argparse
from pathlib import Path

from ray3d.cli.commands import write_json
from ray3d.errors import InputError


def _show(files: list[Path], what: str = "") -> int:
    """Print a benchmark's markdown table (the ``.md`` among its ``files``) and where its files went."""
    for path in files:
        if path.suffix == ".md":
            print(path.read_text())
    print(f"{what + ' ' if what else ''}-> {', '.join(map(str, files))}")
    return 0


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
    return _show(write(rows, args.out), f"{len(rows)} estimates")


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
            from ray3d.options import VideoOptions
            from ray3d.video import make_detector, track_video

            camera = read_camera(args.camera)
            keypoints = track_video(args.video, camera, make_detector(args.detector, camera),
                                    VideoOptions(fps=args.fps)).keypoints()
            name = args.video.name
        video_rows = run_video(lifter, keypoints, read_camera(args.camera), args.smooth_3d)
    emulated = run_emulated(lifter, motion_data.load_shipped(args.data_dir, "test"), args.pairs, args.seed,
                            smooth_3d=args.smooth_3d, layout=args.emulated_layout)
    return _show(write(args.out, emulated, video_rows, name))


def real_near(args: argparse.Namespace) -> int:
    from ray3d.bench.real_near import VIEWS, run, write
    from ray3d.lift import Lifter

    return _show(write(args.out, run(args.data, args.detector, Lifter.load(args.checkpoint),
                                     tuple(args.views or VIEWS))))


def speed(args: argparse.Namespace) -> int:
    from ray3d.bench.speed import measure_all
    from ray3d.io.atomic import check_output, refuse_existing

    if args.json is not None:  # refused before the minutes of measuring, not after them
        refuse_existing(check_output(args.json, argument="json"), args.force)
    camera = None
    if args.video is not None:
        from ray3d.io.camera_files import read_camera

        if args.camera is None:
            raise InputError("bench speed: --video needs --camera")
        camera = read_camera(args.camera)
    result = measure_all(args.models, args.repeats, args.video, camera, args.video_frames, batch_size=args.batch,
                         sequence_frames=args.sequence_frames, train_batch=args.train_batch)
    by_path = ", ".join(f"{name.removesuffix('_gflops')} {rate:.0f}"
                        for name, rate in result["matmul_paths_gflops"].items())
    print(f"fp32 matmul peak: {result['matmul_peak_gflops']:.0f} GFLOP/s ({by_path}); memory "
          f"{result['memory_gbps']:.1f} GB/s; BLAS {result['blas']}; torch threads {result['torch_threads']}")
    print(f"{'model':<15}{'backend':<13}{'params':>12}{'MFLOP/f':>9}{'batch f/s':>11}{'seq f/s':>10}"
          f"{'latency ms':>11}{'stream ms':>10}{'train s/s':>10}{'loop s/s':>10}{'% peak':>8}")
    for r in result["models"]:
        train_rate, loop_rate = (f"{r[key]:>10,.0f}" if r.get(key) else f"{'-':>10}"
                                 for key in ("train_samples_per_s", "train_loop_samples_per_s"))
        print(f"{r['model']:<15}{r['backend']:<13}{r['params']:>12,}{r['mflops_per_frame']:>9.2f}"
              f"{r['batch_frames_per_s']:>11,.0f}{r['sequence_frames_per_s']:>10,.0f}{r['latency_ms']:>11.2f}"
              f"{r['stream_ms_per_frame']:>10.2f}{train_rate}{loop_rate}{100 * r['fraction_of_peak']:>8.1f}")
    torch_rows = [r for r in result["models"] if r["backend"] == "torch"]
    print("torch, the inference form (models.inference) against the network as trained, same run:")
    print("\n".join(f"  {r['model']:<15}batch {r['batch_frames_per_s']:,.0f} / "
                    f"{r['training_form']['batch_frames_per_s']:,.0f} f/s, latency {r['latency_ms']:.2f} / "
                    f"{r['training_form']['latency_ms']:.2f} ms" for r in torch_rows))
    print("the machine's bounds (at the matmul peak; latency: reading the fp32 weights once):")
    for r in torch_rows:
        paths = "; ".join(f"{layer} {'+'.join(ops)}" for layer, ops in r["layer_gemm_paths"].items())
        print(f"  {r['model']:<15}batch <= {r['bound_batch_frames_per_s']:,.0f} f/s, train <= "
              f"{r['bound_train_samples_per_s']:,.0f} s/s, latency >= {r['bound_latency_ms']:.2f} ms; {paths}")
    if result["video"]:
        v = result["video"]
        print(f"ray3d video, {v['frames']} frames of {v['video']} ({v['people']} people): people "
              f"{v['people_frames_per_s']:.1f} f/s, lifting {v['lifting_frames_per_s']:.1f} f/s, writing "
              f"{v['writing_frames_per_s']:.1f} f/s, end to end {v['end_to_end_frames_per_s']:.1f} f/s")
    if args.json:
        write_json(args.json, result, args.force)
    return 0
