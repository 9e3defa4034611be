"""The ``ray3d`` argument parser: every subcommand, its flags and their help, each bound to its handler."""

from __future__ import annotations

import argparse
from pathlib import Path

import ray3d
from ray3d.body import ADULT_STATURE_M
from ray3d.io.world import WRITTEN_FORMATS
from ray3d.cli import bench_commands as bench_handlers
from ray3d.cli import commands as handlers
from ray3d.cli import fusion_commands as fusion_handlers
from ray3d.cli import live_commands as live_handlers
from ray3d.cli import site_commands as site_handlers
from ray3d.cli import video_commands as video_handlers
from ray3d.cli.arguments import (add_camera_arguments, add_data_dir, add_force, add_lens_arguments,
                                 add_lifting_arguments, add_precision, add_time_buckets)


def _import_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output motion npz (the shipped format)")
    parser.add_argument("--fps", type=float, default=60.0, help="output frame rate (default 60)")
    parser.add_argument("--drop-frames", type=int, default=0, metavar="N",
                        help="leading native frames to discard, e.g. a synthetic T-pose")
    parser.add_argument("--no-floor", action="store_true", help="keep z as in the file (no floor at z = 0)")
    parser.add_argument("--subject", default="user", help="performer name stored with the clips")
    add_force(parser, "replace OUT if it exists")


class OneLineErrors(argparse.ArgumentParser):
    """A parser whose errors are one line (not the usage block): bad input is one line and exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from ray3d.checkpoints import DETECTOR_MODEL
    from ray3d.data.virtual_cameras import SET_NAMES
    from ray3d.video.detectors import DEFAULT_DETECTOR, DETECTOR_HELP

    parser = OneLineErrors(
        prog="ray3d", description="Absolute 3D human pose in world coordinates from one calibrated camera.")
    parser.add_argument("--version", action="version", version=f"ray3d {ray3d.__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = commands.add_parser("demo", help="the main job: lift a bundled clip, compare with the truth and "
                                            "the baselines, write an HTML viewer and a GIF")
    demo.add_argument("--out", type=Path, default=Path("ray3d-demo"), help="output folder (default ray3d-demo)")
    demo.add_argument("--checkpoint", default="ray3d", help="model to demonstrate (default: the shipped Ray3D)")
    demo.add_argument("--frames", type=int, help="use only the first N frames")
    demo.set_defaults(handler=handlers.demo)

    data = commands.add_parser("data", help="motion data: info, importers, virtual camera sets")
    data_commands = data.add_subparsers(dest="data_command", metavar="DATA_COMMAND", required=True)

    info = data_commands.add_parser("info", help="what motion data is available: clips, frames, minutes, splits")
    add_data_dir(info)
    info.set_defaults(handler=handlers.data_info)

    bvh = data_commands.add_parser("import-bvh", help="BVH takes -> a motion npz (H36M-17, metres, z up)")
    bvh.add_argument("files", nargs="+", type=Path, metavar="FILE")
    bvh.add_argument("--units", choices=["m", "cm", "mm", "inch", "cmu"],
                     help="file length units (default: CMU units for cgspeed namings, cm for Daz)")
    _import_common(bvh)
    bvh.set_defaults(handler=handlers.import_bvh)

    amc = data_commands.add_parser("import-amc", help="an ASF skeleton and AMC takes -> a motion npz")
    amc.add_argument("asf", type=Path, metavar="ASF")
    amc.add_argument("amc", nargs="+", type=Path, metavar="AMC")
    amc.add_argument("--native-fps", type=float, default=120.0, help="the AMC files' frame rate (default 120)")
    _import_common(amc)
    amc.set_defaults(handler=handlers.import_amc)

    cams = data_commands.add_parser("cameras", help="write a named virtual camera set as JSON")
    cams.add_argument("--set", required=True, choices=SET_NAMES)
    cams.add_argument("--out", required=True, type=Path)
    cams.add_argument("--split", default="test", choices=["train", "validation", "test", "all"],
                      help="clips the cameras must see entirely (default: test)")
    cams.add_argument("--no-filter", action="store_true", help="write the whole grid, without the in-image filter")
    add_data_dir(cams)
    add_force(cams, "replace OUT if it exists")
    cams.set_defaults(handler=handlers.cameras)

    train = commands.add_parser("train", help="train a model on the training performers with random cameras")
    train.add_argument("--config", type=Path, help="training config JSON (see configs/); default: Ray3D lite")
    train.add_argument("--preset", help="model preset replacing the config's model (ray3d, videopose3d, rie, ...)")
    train.add_argument("--out", required=True, type=Path, help="run folder: best.*, last.*, config.json")
    train.add_argument("--resume", action="store_true", help="continue the run in --out from its last epoch")
    train.add_argument("--epochs", type=int)
    train.add_argument("--batches-per-epoch", type=int)
    train.add_argument("--batch-size", type=int)
    train.add_argument("--seed", type=int)
    train.add_argument("--threads", type=int, help="torch CPU threads per process")
    add_data_dir(train)
    train.add_argument("--quiet", action="store_true", help="no progress bar or per-epoch lines")
    train.set_defaults(handler=handlers.train)

    evaluation = commands.add_parser("evaluate", help="MPJPE, P-MPJPE, Abs-MPJPE, MRPE of a model on mocap clips")
    evaluation.add_argument("--checkpoint", default="ray3d",
                            help="a checkpoint path or a shipped model name (ray3d, videopose3d, rie, ...) or rfrh")
    evaluation.add_argument("--mocap", type=Path, help="a motion npz (default: the shipped mocap's test performers)")
    evaluation.add_argument("--split", choices=["train", "validation", "test", "all"],
                            help="clips to use (default: test for the shipped files, all for any other npz)")
    evaluation.add_argument("--cameras", required=True, help=f"a camera set ({', '.join(SET_NAMES)}) or a cameras JSON")
    evaluation.add_argument("--datasets", help="with the shipped mocap: cmu, hdm05 or cmu,hdm05 (default both)")
    evaluation.add_argument("--joints", choices=["h36m17", "h36m14"], default="h36m17",
                            help="joints scored (h36m14: without spine, thorax and neck/nose)")
    evaluation.add_argument("--noise-px", type=float, default=0.0,
                            help="Gaussian noise on the 2D input, standard deviation in pixels (a detector's jitter)")
    evaluation.add_argument("--flip-test", action="store_true", help="average with the mirrored input's prediction")
    evaluation.add_argument("--refine", action="store_true",
                            help="lift each (camera, clip) as a track with the track-level refinement, as ray3d lift does")
    evaluation.add_argument("--frame-stride", type=int, default=1, help="evaluate every N-th frame (default 1)")
    add_precision(evaluation)
    evaluation.add_argument("--json", type=Path, help="write the results here")
    add_force(evaluation, "replace --json if it exists")
    add_data_dir(evaluation)
    evaluation.set_defaults(handler=handlers.evaluate)

    lift = commands.add_parser("lift", help="2D keypoints + a calibrated camera -> 3D joints in world metres")
    lift.add_argument("--keypoints", required=True, type=Path, action="append",
                      help="npz / JSON / CSV (ours), COCO results JSON, an OpenPose folder, or VideoPose3D positions_2d "
                           "npz; several, one per camera (each with its --camera): one fused world")
    add_camera_arguments(lift, several=True)
    lift.add_argument("--find-offsets", action="store_true", help="several keypoint files: find how far apart their "
                                                                  "clocks are from the people both cameras see")
    lift.add_argument("--out", required=True, type=Path,
                      help="output .json, .csv or .npz (read back by ray3d viz), .trc (OpenSim / Pose2Sim markers) or "
                           ".bvh (a skeleton with joint rotations: Blender, Maya; one file per track)")
    lift.add_argument("--layout", help="joint layout of the keypoints (h36m17, coco17, halpe26, blazepose33, body25, ...)")
    lift.add_argument("--fps", type=float, help="frame rate of the keypoints (default: from the file, else 60)")
    add_lifting_arguments(lift)
    lift.add_argument("--subject", help="VideoPose3D npz: the subject")
    lift.add_argument("--action", help="VideoPose3D npz: the action")
    lift.add_argument("--camera-index", type=int, help="VideoPose3D npz: the camera index (0-3)")
    add_force(lift, "replace --out if it exists")
    lift.set_defaults(handler=fusion_handlers.lift)

    video = commands.add_parser("video", help="a video -> every person's 2D detections and track -> world 3D, "
                                              "viewer and overlay video (pip install 'ray3d[video]'); several "
                                              "videos, one per camera: one world, one track per person")
    video.add_argument("input", type=Path, nargs="+", help="the video file(s) (anything OpenCV reads: .mp4, .avi, "
                                                           "...); several: one per calibrated camera, in step")
    add_camera_arguments(video, image_size_note=" (default: the video's)", several=True)
    video.add_argument("--find-offsets", action="store_true", help="several videos: find how far apart they "
                                                                   "started from the people both see")
    video.add_argument("--out", required=True, type=Path, help="folder for world.*, keypoints.json, viewer.html, "
                                                                "overlay.mp4")
    video.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    video.add_argument("--start", type=int, default=0, help="first frame to process (default 0)")
    video.add_argument("--frames", type=int, help="how many frames to process (default: to the end)")
    video.add_argument("--max-gap", type=float, default=0.5,
                       help="seconds a person may go undetected and keep their track (default 0.5)")
    video.add_argument("--min-track", type=float, default=1.0, help="drop tracks shorter than this, seconds (default 1)")
    video.add_argument("--rejoin", type=float, default=3.0,
                       help="take a person up again after a gap of up to this many seconds where their walk led, in "
                            "the same clothes: one identity (default 3; 0: never)")
    video.add_argument("--format", choices=WRITTEN_FORMATS, default=".json",
                       help="world file format (.trc: OpenSim / Pose2Sim markers; .bvh: one skeleton per track)")
    video.add_argument("--fps", type=float, help="override the frame rate the video reports")
    video.add_argument("--no-overlay", action="store_true", help="skip the overlay video")
    video.add_argument("--site", type=Path, help="also analyse the people on this site file's zones and lines: a "
                       "report, tables and plots in OUT/site (as ray3d site does; docs/site.md)")
    add_time_buckets(video)
    video.add_argument("--privacy", action="store_true", help="write nothing derived from the pixels but "
                       "skeletons, tracks and events: no overlay video")
    # Detector keypoints of real footage: the model trained for them.
    add_lifting_arguments(video)
    add_force(video, "replace existing outputs in --out")
    video.set_defaults(handler=video_handlers.video)

    fuse = commands.add_parser("fuse", help="several cameras' world files (ray3d lift / video, one per camera) -> "
                                            "one world, one track per person, joints fused where cameras overlap")
    fuse.add_argument("worlds", nargs="+", type=Path, help="world files (.json/.csv/.npz), one per camera; the "
                                                           "first sets the clock and frame numbers")
    fuse.add_argument("--out", required=True, type=Path, help="the fused world file (.json)")
    fuse.add_argument("--offsets", help="seconds each camera's clock is ahead of the first's, comma separated "
                                        "(the first 0; default all 0)")
    fuse.add_argument("--find-offsets", action="store_true", help="find the offsets from the people both cameras "
                                                                  "see at once")
    fuse.add_argument("--max-offset", type=float, default=2.0, help="the largest offset searched, seconds (default 2)")
    fuse.add_argument("--handover", type=float, default=2.0,
                      help="a person leaving one view and entering another within this many seconds keeps their "
                           "track (default 2)")
    add_force(fuse, "replace --out if it exists")
    fuse.set_defaults(handler=fusion_handlers.fuse)

    live_handlers.add_parser(commands)

    batch = commands.add_parser("batch", help="every video and keypoint file of a manifest, each one task on a Ray "
                                              "cluster or a local Ray (pip install 'ray3d[cluster]')")
    batch.add_argument("manifest", type=Path, help="CSV or JSON: input, camera (or camera_height, pitch, hfov), "
                                                   "options (docs/batch.md)")
    batch.add_argument("--out", required=True, type=Path, help="output folder: NAME/ per input and summary.csv")
    batch.add_argument("--address", help="an existing Ray cluster: auto, or ray://HOST:10001 (default: start a "
                                         "local Ray for this job)")
    batch.add_argument("--workers", type=int, help="local Ray: its CPUs (default all); on a cluster: most tasks "
                                                   "at once (default no limit)")
    batch.add_argument("--retries", type=int, default=2,
                       help="retries of a task that crashed or raised (default 2; a bad input is not retried)")
    batch.add_argument("--cpus-per-task", type=float, default=1, help="CPUs (torch threads) per task (default 1)")
    batch.add_argument("--gpus-per-task", type=float, default=0, help="GPUs per task (default 0)")
    batch.set_defaults(handler=handlers.batch)

    viz = commands.add_parser("viz", help="an HTML viewer and/or a GIF/MP4 of lifted 3D (outputs of ray3d lift or "
                                          "ray3d video): every track, with its id and path on the floor")
    viz.add_argument("world", nargs="+", type=Path,
                     help="world files (.json/.csv/.npz): several people, or one per method to compare")
    viz.add_argument("--camera", help="the camera drawn and projected through (default: the first world file's)")
    viz.add_argument("--html", type=Path, help="write the interactive viewer here")
    viz.add_argument("--animation", type=Path, help="write a .gif or .mp4 here (MP4 for long clips: bounded memory)")
    viz.add_argument("--track", help="show only this track (default: every track)")
    viz.add_argument("--keypoints", type=Path,
                     help="the 2D input (e.g. ray3d video's keypoints.json): drawn under the lifted joints")
    viz.add_argument("--fps", type=float, help="playback frame rate (default: the world file's)")
    viz.add_argument("--stride", type=int, default=2, help="animation: every N-th frame (default 2)")
    add_force(viz, "replace existing outputs")
    viz.set_defaults(handler=handlers.viz)

    site_handlers.add_parser(commands)

    bench = commands.add_parser("bench", help="benchmarks: robustness sweeps, speed")
    bench_commands = bench.add_subparsers(dest="bench_command", metavar="BENCH_COMMAND", required=True)
    robustness = bench_commands.add_parser("robustness", help="the paper's robustness sweeps (CSV, markdown, PNG)")
    robustness.add_argument("--out", required=True, type=Path, help="folder for the sweep files")
    robustness.add_argument("--models", nargs="+", default=["ray3d", "videopose3d", "rie", "rfrh"],
                            help="shipped names, checkpoint paths or rfrh, optionally LABEL=MODEL (default: the "
                                 "shipped ones and rfrh)")
    robustness.add_argument("--frame-stride", type=int, default=4, help="score every N-th frame (default 4)")
    robustness.add_argument("--camera-stride", type=int, default=1, help="use every N-th camera of each set")
    robustness.add_argument("--clips", type=int, help="use only the first N test clips (quick runs)")
    add_data_dir(robustness)
    robustness.set_defaults(handler=bench_handlers.robustness)
    calibration = bench_commands.add_parser("calibration", help="camera estimation from a walking person: errors "
                                                                "and their cost to Ray3D (CSV, JSON, markdown)")
    calibration.add_argument("--out", required=True, type=Path, help="folder for calibration.{csv,json,md}")
    calibration.add_argument("--pairs", type=int, default=12, help="random (camera, walking clip) pairs")
    calibration.add_argument("--bootstrap", type=int, default=30, help="bootstrap resamples per estimate")
    calibration.add_argument("--people", type=int, default=1,
                             help="walking clips seen at once by each camera, fitted jointly (default 1)")
    calibration.add_argument("--checkpoint", default="ray3d", help="the model that lifts (default ray3d)")
    calibration.add_argument("--seed", type=int, default=0)
    calibration.add_argument("--split", choices=["train", "validation", "test"], default="test",
                             help="whose walking clips (default: the test performers)")
    add_data_dir(calibration)
    calibration.set_defaults(handler=bench_handlers.calibration)
    real = bench_commands.add_parser("real-video", help="physical checks (feet on the floor, stature, walking speed, "
                                                        "bones, skating, jitter) on a video and on emulated detections")
    real.add_argument("--out", required=True, type=Path, help="folder for real-video.{json,md}")
    real.add_argument("--video", type=Path, help="a video of people walking on a floor (needs --camera)")
    real.add_argument("--keypoints", type=Path, help="instead of --video: its detections (e.g. ray3d video's keypoints.json)")
    real.add_argument("--camera", help="the video's camera file")
    real.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    real.add_argument("--fps", type=float, help="the video's or keypoints' frame rate, if they do not say")
    real.add_argument("--smooth-3d", choices=["savgol", "one-euro"], help="smooth the lifted joints in time")
    real.add_argument("--checkpoint", default="ray3d", help="the model that lifts (default ray3d)")
    real.add_argument("--pairs", type=int, default=12, help="emulated (test clip, camera) pairs (default 12)")
    real.add_argument("--emulated-layout", choices=["h36m17", "coco17"],
                      help="what the emulated detector reports (default: what the model reads, H36M-17 or COCO-17)")
    real.add_argument("--seed", type=int, default=0)
    add_data_dir(real)
    real.set_defaults(handler=bench_handlers.real_video)
    near = bench_commands.add_parser("real-near", help="near, low real cameras against 3D truth: each view of "
                                     "../shared/data/real-near through ray3d video's finder and lifter")
    near.add_argument("--data", type=Path, default=Path("../shared/data/real-near"),
                      help="the real-near folder (default ../shared/data/real-near)")
    near.add_argument("--out", required=True, type=Path, help="folder for real-near.{json,md}")
    near.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    near.add_argument("--checkpoint", default=DETECTOR_MODEL, help=f"the model that lifts (default {DETECTOR_MODEL})")
    near.add_argument("--views", nargs="+", help="which cameras (default: cam01 cam02 cam03 cam04)")
    near.add_argument("--floor-offset", type=float, default=0.0, metavar="M",
                      help="give each camera with its z = 0 this far above the floor (a calibration board on a "
                           "table; negative: below), default 0")
    near.set_defaults(handler=bench_handlers.real_near)
    level = bench_commands.add_parser("level", help="low, nearly level cameras (the level-test set) through an "
                                      "emulated detector with real detectors' joint offsets, beside the floor guess")
    level.add_argument("--out", required=True, type=Path, help="folder for level.{json,md}")
    level.add_argument("--checkpoint", default=DETECTOR_MODEL, help=f"the model that lifts (default {DETECTOR_MODEL})")
    level.add_argument("--clips-per-camera", type=int, default=1, help="test clips per camera (default 1)")
    level.add_argument("--max-frames", type=int, default=300, help="frames of each clip, at 30 frames/s (default 300)")
    level.add_argument("--seed", type=int, default=0)
    level.add_argument("--floor-offset", type=float, default=0.0, metavar="M",
                       help="give the lifter and the guess each camera with its z = 0 this far above the floor (a "
                            "calibration board on a table; negative: below), default 0")
    level.add_argument("--camera-step", type=int, default=1, metavar="N", help="every Nth camera of the set (default 1)")
    level.add_argument("--floor-z", type=float, metavar="M", help="tell the lifter the floor lies here in the given "
                       "camera's frame (0: its z = 0 assumed to be the floor; default: observed from the people)")
    add_data_dir(level)
    level.set_defaults(handler=bench_handlers.level)
    speed_bench = bench_commands.add_parser("speed", help="inference and training speed of every model preset")
    speed_bench.add_argument("--json", type=Path, help="write the results here")
    speed_bench.add_argument("--models", nargs="+", help="presets to measure (default: ray3d ray3d-paper; all: every preset)")
    speed_bench.add_argument("--rounds", type=int, default=7,
                             help="interleaved rounds: every figure and bound timed once per round (median)")
    speed_bench.add_argument("--batch", type=int, default=1024, help="windows per inference batch")
    speed_bench.add_argument("--train-batch", type=int, default=1024)
    speed_bench.add_argument("--video", type=Path, help="also time ray3d video on this video (the video extra)")
    speed_bench.add_argument("--camera", type=Path, help="the video's camera file")
    speed_bench.add_argument("--video-frames", type=int, default=100, help="frames of --video to time")
    add_force(speed_bench, "replace --json if it exists")
    speed_bench.set_defaults(handler=bench_handlers.speed)

    calibrate = commands.add_parser("calibrate", help="a camera from floor points with known positions, or from a "
                                                      "person walking on the floor")
    calibrate.add_argument("--floor-points", type=Path,
                           help="CSV (x,y,u,v) or JSON list: floor positions in metres and their pixels, 4 or more")
    calibrate.add_argument("--from-person", type=Path, metavar="KEYPOINTS",
                           help="instead of --floor-points: 2D keypoints of one person standing or walking on the "
                                "floor (any format ray3d lift reads); estimates height, pitch, roll (and focal)")
    calibrate.add_argument("--person-height", type=float, default=ADULT_STATURE_M,
                           help=f"with --from-person: the person's stature in metres (default {ADULT_STATURE_M:.2f})")
    calibrate.add_argument("--track", help="with --from-person: only this track (default: every track, jointly)")
    calibrate.add_argument("--layout", help="with --from-person: joint layout of the keypoints")
    calibrate.add_argument("--intrinsics", help="a camera file whose intrinsics (and distortion) to keep")
    add_lens_arguments(calibrate, "instead of --intrinsics (with --from-person: --focal/--hfov if known)")
    calibrate.add_argument("--out", required=True, type=Path, help="camera JSON to write")
    add_force(calibrate, "replace --out if it exists")
    calibrate.set_defaults(handler=handlers.calibrate)

    models = commands.add_parser("models", help="the model presets: size, FLOPs per frame, which are shipped")
    models.set_defaults(handler=handlers.models)

    exporting = commands.add_parser("export", help="a trained checkpoint -> inference weights (.safetensors + .json)")
    exporting.add_argument("--checkpoint", default="ray3d", help="a shipped model name or e.g. runs/NAME/best.safetensors")
    exporting.add_argument("--out", required=True, type=Path, help="target .safetensors (its .json is written beside)")
    exporting.add_argument("--onnx", action="store_true", help="write ONNX to --out instead (pip install 'ray3d[onnx]')")
    exporting.add_argument("--image-width", type=float, default=1000.0,
                           help="with --onnx: the image width pixel-input models normalise by (default 1000)")
    exporting.add_argument("--last-weights", action="store_true",
                           help="from a run with ema_decay: the last trained weights instead of their moving average")
    exporting.add_argument("--command-line", help="the training command, recorded with the weights")
    exporting.add_argument("--time-s", type=float, help="training wall time, recorded with the weights")
    exporting.add_argument("--machine", help="where it was trained, recorded with the weights")
    add_force(exporting, "replace --out if it exists")
    exporting.set_defaults(handler=handlers.export)

    speed = data_commands.add_parser("samples-speed", help="measure the training-sample generator's throughput")
    speed.add_argument("--batch", type=int, default=1024)
    speed.add_argument("--frames", type=int, default=9)
    speed.add_argument("--repeats", type=int, default=20)
    add_data_dir(speed)
    speed.set_defaults(handler=handlers.samples_speed)
    return parser
