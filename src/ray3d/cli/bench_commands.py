"""The ``ray3d bench`` handlers: each parses nothing, calls one benchmark of ``ray3d.bench`` and prints where its
files went."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ray3d.cli.arguments import add_data_dir, add_force, add_out
from ray3d.cli.printing import write_json
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
        print(f"ray3d video, {v['frames']} frames of {v['video']} ({v['people']} people): people "
              f"{v['people_frames_per_s']:.1f} f/s, lifting {v['lifting_frames_per_s']:.1f} f/s, writing "
              f"{v['writing_frames_per_s']:.1f} f/s, end to end {v['end_to_end_frames_per_s']:.1f} f/s")
    if args.json:
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
    print(json.dumps({k: v for k, v in result.items() if k != "rss_mb_samples"}, indent=1))
    write_json(args.out / f"{args.mode}.json", result, False)
    return 0


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
    print(json.dumps(result, indent=1))
    write_json(args.out / ("fusion-live.json" if args.live else "fusion.json"), result, args.force)
    return 0


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


def add_parser(commands) -> None:
    """``ray3d bench`` and its subcommands's flags, each bound to its handler here."""
    from pathlib import Path

    from ray3d.checkpoints import DETECTOR_MODEL
    from ray3d.video.detectors import DEFAULT_DETECTOR, DETECTOR_HELP

    bench_parser = commands.add_parser("bench", help="benchmarks: accuracy, speed, identities, live, fusion")
    bench_commands_parser = bench_parser.add_subparsers(dest="bench_command", metavar="BENCH_COMMAND", required=True)
    robustness_parser = _subcommand(bench_commands_parser, "robustness", robustness,
                                    "the paper's robustness sweeps (CSV, markdown, PNG)")
    add_out(robustness_parser, "folder for the sweep files")
    robustness_parser.add_argument("--models", nargs="+", default=["ray3d", "videopose3d", "rie", "rfrh"],
                            help="shipped names, checkpoint paths or rfrh, optionally LABEL=MODEL (default: the "
                                 "shipped ones and rfrh)")
    robustness_parser.add_argument("--frame-stride", type=int, default=4, help="score every N-th frame (default 4)")
    robustness_parser.add_argument("--camera-stride", type=int, default=1, help="use every N-th camera of each set")
    robustness_parser.add_argument("--clips", type=int, help="use only the first N test clips (quick runs)")
    add_data_dir(robustness_parser)
    calibration_parser = _subcommand(bench_commands_parser, "calibration", calibration,
                                     "camera estimation from a walking person: errors "
                                     "and their cost to Ray3D (CSV, JSON, markdown)")
    add_out(calibration_parser, "folder for calibration.{csv,json,md}")
    calibration_parser.add_argument("--pairs", type=int, default=12, help="random (camera, walking clip) pairs")
    calibration_parser.add_argument("--bootstrap", type=int, default=30, help="bootstrap resamples per estimate")
    calibration_parser.add_argument("--people", type=int, default=1,
                             help="walking clips seen at once by each camera, fitted jointly (default 1)")
    _checkpoint(calibration_parser, "ray3d")
    calibration_parser.add_argument("--seed", type=int, default=0)
    calibration_parser.add_argument("--split", choices=["train", "validation", "test"], default="test",
                             help="whose walking clips (default: the test performers)")
    add_data_dir(calibration_parser)
    real_parser = _subcommand(bench_commands_parser, "real-video", real_video,
                              "physical checks (feet on the floor, stature, walking speed, "
                              "bones, skating, jitter) on a video and on emulated "
                              "detections")
    add_out(real_parser, "folder for real-video.{json,md}")
    real_parser.add_argument("--video", type=Path, help="a video of people walking on a floor (needs --camera)")
    real_parser.add_argument("--keypoints", type=Path,
                             help="instead of --video: its detections (e.g. ray3d video's keypoints.json)")
    real_parser.add_argument("--camera", help="the video's camera file")
    real_parser.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    real_parser.add_argument("--fps", type=float, help="the video's or keypoints' frame rate, if they do not say")
    real_parser.add_argument("--smooth-3d", choices=["savgol", "one-euro"], help="smooth the lifted joints in time")
    _checkpoint(real_parser, "ray3d")
    real_parser.add_argument("--pairs", type=int, default=12, help="emulated (test clip, camera) pairs (default 12)")
    real_parser.add_argument("--emulated-layout", choices=["h36m17", "coco17"],
                      help="what the emulated detector reports (default: what the model reads, H36M-17 or COCO-17)")
    real_parser.add_argument("--seed", type=int, default=0)
    add_data_dir(real_parser)
    near_parser = _subcommand(bench_commands_parser, "real-near", real_near,
                              "near, low real cameras against 3D truth: each view of "
                              "../shared/data/real-near through ray3d video's finder and "
                              "lifter")
    near_parser.add_argument("--data", type=Path, default=Path("../shared/data/real-near"),
                      help="the real-near folder (default ../shared/data/real-near)")
    add_out(near_parser, "folder for real-near.{json,md}")
    near_parser.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    _checkpoint(near_parser, DETECTOR_MODEL)
    near_parser.add_argument("--views", nargs="+", help="which cameras (default: cam01 cam02 cam03 cam04)")
    near_parser.add_argument("--floor-offset", type=float, default=0.0, metavar="M",
                      help="give each camera with its z = 0 this far above the floor (a calibration board on a "
                           "table; negative: below), default 0")
    level_parser = _subcommand(bench_commands_parser, "level", level,
                               "low, nearly level cameras (the level-test set) through an "
                               "emulated detector with real detectors' joint offsets, "
                               "beside the floor guess")
    add_out(level_parser, "folder for level.{json,md}")
    _checkpoint(level_parser, DETECTOR_MODEL)
    level_parser.add_argument("--clips-per-camera", type=int, default=1, help="test clips per camera (default 1)")
    level_parser.add_argument("--max-frames", type=int, default=300,
                              help="frames of each clip, at 30 frames/s (default 300)")
    level_parser.add_argument("--seed", type=int, default=0)
    level_parser.add_argument("--floor-offset", type=float, default=0.0, metavar="M",
                       help="give the lifter and the guess each camera with its z = 0 this far above the floor (a "
                            "calibration board on a table; negative: below), default 0")
    level_parser.add_argument("--population-scale", type=float, default=1.0, metavar="F",
                              help="every person's size times F (1.04: a population 4 %% taller than the prior's)")
    level_parser.add_argument("--camera-step", type=int, default=1, metavar="N",
                              help="every Nth camera of the set (default 1)")
    level_parser.add_argument("--floor-z", type=float, metavar="M",
                              help="tell the lifter the floor lies here in the given camera's frame (0: its z = 0 "
                                   "assumed to be the floor; default: decided on the people)")
    add_data_dir(level_parser)
    speed_bench_parser = _subcommand(bench_commands_parser, "speed", speed,
                                     "inference and training speed of every model preset")
    speed_bench_parser.add_argument("--json", type=Path, help="write the results here")
    speed_bench_parser.add_argument("--models", nargs="+",
                                    help="presets to measure (default: ray3d ray3d-paper; all: every preset)")
    speed_bench_parser.add_argument("--rounds", type=int, default=7,
                             help="interleaved rounds: every figure and bound timed once per round (median)")
    speed_bench_parser.add_argument("--batch", type=int, default=1024, help="windows per inference batch")
    speed_bench_parser.add_argument("--train-batch", type=int, default=1024)
    speed_bench_parser.add_argument("--video", type=Path, help="also time ray3d video on this video (the video extra)")
    speed_bench_parser.add_argument("--camera", type=Path, help="the video's camera file")
    speed_bench_parser.add_argument("--video-frames", type=int, default=100, help="frames of --video to time")
    add_force(speed_bench_parser, "replace --json if it exists")
    identity_parser = _subcommand(bench_commands_parser, "identity", identity,
                                  "who is who: ray3d video's tracker, ByteTrack, "
                                  "OC-SORT, SORT against identities annotated by hand (IDF1)")
    _video_and_camera(identity_parser, "detections.npz, the trackers' MOT files and identities.json")
    identity_parser.add_argument("--detections", type=Path, help="an earlier run's detections.npz (default: detect)")
    identity_parser.add_argument("--annotation", type=Path,
                                 help="frame, person, x0, y0, x1, y1 per box (default: the shipped one of vtest.avi)")
    identity_parser.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    identity_parser.add_argument("--min-track-s", type=float, default=1.0,
                                 help="leave out every tracker's tracks followed for less (default 1, as ray3d video)")
    people_parser = _subcommand(bench_commands_parser, "people", people,
                                "everyone in view: the annotated people ray3d "
                                "video's detector finds, by facing, crowding, hiding, height")
    _video_and_camera(people_parser, "people.json")
    people_parser.add_argument("--finders", nargs="+", default=["none", "movenet-384"],
                               help="full-frame finders: none, or movenet-SIZE[-COLUMNSxROWS] (default: both)")
    people_parser.add_argument("--finder-every", type=int, default=2, help="the finder every n-th frame (default 2)")
    people_parser.add_argument("--annotation", type=Path, help="the people (default: the shipped ones of vtest.avi)")
    add_force(people_parser, "replace people.json if it exists")
    live_parser = _subcommand(bench_commands_parser, "live", live,
                              "ray3d live as a service runs it, measured from "
                              "outside: soak, restarts, rtsp (a stream down), cluster (Ray)")
    _video_and_camera(live_parser, "the runs and MODE.json (a new folder)")
    live_parser.add_argument("--mode", choices=["soak", "restarts", "rtsp", "cluster"], required=True)
    live_parser.add_argument("--site", type=Path, help="a site file: its events (restarts: needed for the counts)")
    live_parser.add_argument("--minutes", type=float, default=30.0, help="soak: how long, the video looped (30)")
    live_parser.add_argument("--kills", type=int, default=5, help="restarts: SIGKILLs, each started again (5)")
    live_parser.add_argument("--seed", type=int, default=0, help="restarts: the kills' moments")
    live_parser.add_argument("--seconds", type=float, help="rtsp: how long (75); cluster: each paced run (40)")
    fusion_parser = _subcommand(bench_commands_parser, "fusion", fusion,
                                "several cameras, one world, against known "
                                "truth: test walks seen by 2-4 virtual cameras, fused")
    add_out(fusion_parser, "folder for fusion.json (fusion-live.json)")
    fusion_parser.add_argument("--live", action="store_true", help="frame by frame, as ray3d live lifts and fuses")
    fusion_parser.add_argument("--clips", type=int, default=6, help="test walks (default 6)")
    fusion_parser.add_argument("--cameras", type=int, nargs="+", default=[2, 3, 4],
                               help="each walk seen by this many of the room's cameras, in turn (default 2 3 4)")
    fusion_parser.add_argument("--seed", type=int, default=0, help="the noise and the gaps")
    _checkpoint(fusion_parser, "ray3d")
    add_data_dir(fusion_parser)
    add_force(fusion_parser, "replace the JSON if it exists")
    worlds_parser = _subcommand(bench_commands_parser, "worlds", worlds,
                                "two world files of one scene, track by track: "
                                "how far apart they put the same people")
    worlds_parser.add_argument("first", type=Path, help="a world file; each of its tracks is matched")
    worlds_parser.add_argument("second", type=Path, help="the world file its tracks are matched in")
    worlds_parser.add_argument("--min-share", type=float, default=0.5,
                               help="a partner shares at least this share of the track's frames (default 0.5)")


def _subcommand(subcommands, name: str, handler, description: str) -> argparse.ArgumentParser:
    """``ray3d bench NAME``'s parser, bound to ``handler``."""
    parser = subcommands.add_parser(name, help=description)
    parser.set_defaults(handler=handler)
    return parser


def _checkpoint(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--checkpoint", default=default, help=f"the model that lifts (default {default})")


def _video_and_camera(parser, outputs: str) -> None:
    """A video benchmark's video, its camera file and the folder for its ``outputs``."""
    parser.add_argument("video", type=Path, help="the video (vtest.avi for the shipped annotations)")
    parser.add_argument("--camera", required=True, help="the video's camera file")
    add_out(parser, f"folder for {outputs}")
