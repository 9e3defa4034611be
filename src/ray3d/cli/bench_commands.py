"""The ``ray3d bench`` handlers: each parses nothing, calls one benchmark of ``ray3d.bench`` and prints where its
files went."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ray3d.cli.printing import write_json
from ray3d.errors import InputError


def _show(files: list[Path], what: str = "") -> int:
    """Print a benchmark's markdown table (the ``.md`` among its ``files``) and where its files went."""
    for path in files:
        if path.suffix == ".md":
            print(path.read_text())
    print(f"{what + ' ' if what else ''}-> {', '.join(map(str, files))}")
    return 0


def _print_and_write(result: dict, path: Path, overwrite: bool, left_out: tuple[str, ...] = ()) -> int:
    """Print a benchmark's JSON answer (less its long series ``left_out``) and write it whole to ``path``."""
    print(json.dumps({k: v for k, v in result.items() if k not in left_out}, indent=1))
    write_json(path, result, overwrite)
    return 0


def robustness(args: argparse.Namespace) -> int:
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
    from ray3d.jobs import load_lifter

    if args.people < 1:
        raise InputError(f"bench calibration: people must be at least 1, got {args.people}", arguments=("people",))
    rows = run(motion_data.load_shipped(args.data_dir, args.split), load_lifter(args.checkpoint), args.pairs, args.seed,
               args.bootstrap, people=args.people)
    return _show(write(rows, args.out), f"{len(rows)} estimates")


def real_video(args: argparse.Namespace) -> int:
    from ray3d.bench.real_video import run_emulated, run_video, write
    from ray3d.data import motion as motion_data
    from ray3d.io.camera_files import read_camera
    from ray3d.io.keypoints import read_keypoints
    from ray3d.jobs import load_lifter

    lifter, video_rows, name = load_lifter(args.checkpoint), None, ""
    if args.video or args.keypoints:
        if not args.camera:
            raise InputError("bench real-video: --video and --keypoints need --camera")
        if args.keypoints:
            keypoints, name = read_keypoints(args.keypoints, fps=args.fps), args.keypoints.name
        else:
            from ray3d.jobs import CameraChoice, Job, video_input
            from ray3d.lifting.options import VideoOptions
            from ray3d.video import track_video

            job = Job((args.video,), (CameraChoice(str(args.camera)),), detector=args.detector,
                      video=VideoOptions(fps=args.fps))
            keypoints = track_video(*video_input(job, 0), job.video).keypoints()
            name = args.video.name
        video_rows = run_video(lifter, keypoints, read_camera(args.camera), args.smooth_3d)
    emulated = run_emulated(lifter, motion_data.load_shipped(args.data_dir, "test"), args.pairs, args.seed,
                            smooth_3d=args.smooth_3d, layout=args.emulated_layout)
    return _show(write(args.out, emulated, video_rows, name))


def real_near(args: argparse.Namespace) -> int:
    from ray3d.bench.real_near import VIEWS, run, write
    from ray3d.jobs import load_lifter

    _check_floor_offset(args.floor_offset)
    return _show(write(args.out, run(args.data, args.detector, load_lifter(args.checkpoint),
                                     tuple(args.views or VIEWS), args.floor_offset)))


def _check_floor_offset(offset: float) -> None:
    if not np.isfinite(offset) or abs(offset) > 1.0:
        raise InputError(f"bench: the floor offset must be within +/- 1 m, got {offset}", arguments=("floor_offset",))


def level(args: argparse.Namespace) -> int:
    from ray3d.bench.level import run, write
    from ray3d.data import motion as motion_data
    from ray3d.data.virtual_cameras import grid
    from ray3d.jobs import load_lifter

    if args.clips_per_camera < 1 or args.max_frames < 1 or args.camera_step < 1:
        raise InputError("bench level: clips per camera, frames and the camera step must be at least 1",
                         arguments=("clips_per_camera", "max_frames", "camera_step"))
    _check_floor_offset(args.floor_offset)
    rows = run(load_lifter(args.checkpoint), motion_data.load_shipped(args.data_dir, "test"), args.clips_per_camera,
               args.seed, args.max_frames, grid("level-test")[::args.camera_step], args.floor_offset, args.floor_z,
               args.population_scale)
    return _show(write(args.out, rows))


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
    result = measure_all(args.models, args.rounds, args.video, camera, args.video_frames, batch_size=args.batch,
                         train_batch=args.train_batch)
    m = result["machine"]
    print(f"{m['cpu']}, {m['cores']} cores ({m['cpu_capability']}; "
          f"bf16 {'native' if m['bf16_native'] else 'emulated'}), "
          f"torch {m['torch']} on {m['torch_threads']} threads, BLAS {m['blas']}, int8 engine {m['quantized_engine']}, "
          f"oneDNN bf16: {'; '.join(m['onednn_kernels']) or '-'}; {result['rounds']} interleaved rounds, medians")
    print(f"{'model':<13}{'form':<18}{'batch f/s':>10}{'x fp32':>8}{'% fp32 peak':>12}{'% own peak':>11}"
          f"{'latency ms':>11}{'% bound':>8}{'spread b/l':>12}")
    for r in result["inference"]:
        print(f"{r['model']:<13}{r['form']:<18}{r['batch_frames_per_s']:>10,.0f}{r['batch_speedup_over_fp32']:>8.2f}"
              f"{100 * r['batch_fraction_of_fp32_peak']:>12.0f}{100 * r['batch_fraction_of_own_peak']:>11.0f}"
              f"{r['latency_ms']:>11.2f}{100 * r['latency_fraction_of_bound']:>8.0f}"
              f"{r['spread']['batch']:>7.2f}/{r['spread']['latency']:.2f}")
    for r in (r for r in result["inference"] if "peaks_gflops" in r):
        peaks = ", ".join(f"{p} {v:.0f}" for p, v in r["peaks_gflops"].items())
        paths = "; ".join(f"{layer} {'+'.join(ops)}" for layer, ops in r["layer_gemm_paths"].items())
        print(f"  {r['model']}: matmul peaks {peaks} GFLOP/s, memory {r['memory_gbps']:.1f} GB/s (same rounds); fp32 "
              f"bounds: batch <= {r['bound_batch_frames_per_s']:,.0f} f/s, latency >= {r['bound_latency_ms']:.2f} ms; "
              f"{paths}")
    for r in result["training"]:
        loop = ("-" if r["train_loop_samples_per_s"] is None else
                f"{r['train_loop_samples_per_s']:,.0f} ({100 * r['train_loop_fraction_of_bound']:.0f} %)")
        print(f"training {r['model']} (batch {r['train_batch']}): step {r['train_step_samples_per_s']:,.0f} samples/s "
              f"({100 * r['train_step_fraction_of_bound']:.0f} % of the bound, {r['bound_train_samples_per_s']:,.0f}), "
              f"loop with the sample generator {loop}")
    for r in result["streams"]:
        print(f"live push {r['model']}: " + ", ".join(f"{k.removeprefix('stream_ms_')} {v:.2f} ms"
                                                       for k, v in r.items() if k.startswith("stream_ms_")))
    if result["video"]:
        v = result["video"]
        print(f"ray3d video, {v['frames']} frames of {v['video']} ({v['people']} people): " + ", ".join(
            f"{stage.replace('_', ' ')} {v[stage + '_frames_per_s']:.1f} f/s"
            for stage in ("people", "lifting", "writing", "end_to_end")))
    write_json(args.json, result, args.force)
    return 0


def identity(args: argparse.Namespace) -> int:
    from ray3d.bench.identity import ANNOTATION, run, table
    from ray3d.jobs import CameraChoice, Job

    job = Job((args.video,), (CameraChoice(args.camera),), detector=args.detector)
    document = run(job, args.out, args.detections, args.annotation or ANNOTATION, args.min_track_s)
    print(table(document))
    return _show([args.out / "identities.json"])


def live(args: argparse.Namespace) -> int:
    from ray3d.bench import live as bench_live
    from ray3d.bench.restarts import restarts

    camera = str(args.camera)
    if args.mode == "soak":
        result = bench_live.soak(args.video, camera, args.out, args.site, args.minutes)
    elif args.mode == "restarts":
        result = restarts(args.video, camera, args.out, args.site, args.kills, args.seed)
    elif args.mode == "rtsp":
        result = bench_live.rtsp(args.video, camera, args.out, args.site, args.seconds or 75.0)
    else:
        result = bench_live.cluster(args.video, camera, args.out, args.seconds or 40.0)
    return _print_and_write(result, args.out / f"{args.mode}.json", False, left_out=("rss_mb_samples",))


def fusion(args: argparse.Namespace) -> int:
    from ray3d.bench import fusion as bench_fusion
    from ray3d.jobs import load_lifter

    if args.clips < 1:
        raise InputError(f"bench fusion: --clips must be at least 1, got {args.clips}")
    if not set(args.cameras) <= {2, 3, 4}:
        raise InputError(f"bench fusion: --cameras: the room has 2 to 4 cameras, got {args.cameras}")
    walks = bench_fusion.walking_clips(args.clips, args.data_dir)
    measure = bench_fusion.live if args.live else bench_fusion.offline
    result = measure(load_lifter(args.checkpoint), walks, args.seed, tuple(args.cameras))
    return _print_and_write(result, args.out / ("fusion-live.json" if args.live else "fusion.json"), args.force)


def worlds(args: argparse.Namespace) -> int:
    from ray3d.bench.worlds import compare_worlds

    if not 0.0 <= args.min_share <= 1.0:
        raise InputError(f"bench worlds: --min-share is a share of frames, 0 to 1; got {args.min_share}")
    print(json.dumps(compare_worlds(args.first, args.second, args.min_share)))
    return 0


def people(args: argparse.Namespace) -> int:
    from ray3d.bench.people import ANNOTATION, finder_named, read_annotation, row_line, run

    if args.finder_every < 1:
        raise InputError(f"bench people: --finder-every must be at least 1, got {args.finder_every}")
    for name in args.finders:  # a misspelt finder refused before minutes of the others
        finder_named(name)
    annotated = read_annotation(args.annotation or ANNOTATION)
    rows = []
    for finder in args.finders:
        rows.append(run(args.video, str(args.camera), finder, annotated, args.finder_every))
        print(row_line(rows[-1]), flush=True)
    write_json(args.out / "people.json", {"rows": rows}, args.force)
    return 0
