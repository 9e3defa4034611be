"""The arguments several commands share: adding them to a parser, and reading them back into what the
library takes."""

from __future__ import annotations

import argparse
from pathlib import Path

from ray3d.models.precision import PRECISIONS
from ray3d.temporal import OUTPUT_SMOOTHING


def add_data_dir(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data-dir", help="folder with cmu_h36m17.npz / hdm05_h36m17.npz (default: $RAY3D_DATA_DIR "
                        "or ../shared/data/mocap)")


def add_out(parser: argparse.ArgumentParser, what: str, required: bool = True) -> None:
    parser.add_argument("--out", required=required, type=Path, help=what)


def add_people_arguments(parser: argparse.ArgumentParser, short_tracks: str) -> None:
    """How people are found and followed in frames (``ray3d video``, ``ray3d live``); ``short_tracks``: what
    becomes of a track shorter than --min-track."""
    from ray3d.video.detectors import DEFAULT_DETECTOR, DETECTOR_HELP

    parser.add_argument("--detector", default=DEFAULT_DETECTOR, help=DETECTOR_HELP)
    parser.add_argument("--max-gap", type=float, default=0.5,
                        help="seconds a person may go undetected and keep their track (default 0.5)")
    parser.add_argument("--min-track", type=float, default=1.0,
                        help=f"tracks shorter than this (seconds) {short_tracks} (default 1)")


def add_force(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--force", action="store_true", help=what)


def add_lens_arguments(parser: argparse.ArgumentParser, role: str, image_size_note: str = "") -> None:
    parser.add_argument("--hfov", type=float, help=f"{role}: horizontal field of view in degrees")
    parser.add_argument("--focal", type=float, help=f"{role}: focal length in pixels (instead of --hfov)")
    parser.add_argument("--image-size", help=f"{role}: WIDTHxHEIGHT in pixels{image_size_note}")


def add_camera_arguments(parser: argparse.ArgumentParser, image_size_note: str = "", several: bool = False) -> None:
    parser.add_argument("--camera", action="append" if several else "store",
                        help="camera JSON (ours or OpenCV), OpenCV YAML, FILE.toml:NAME (Pose2Sim, Anipose) or "
                             "h36m:SUBJECT:CAMERA_ID" + ("; once per input, in order" if several else ""))
    parser.add_argument("--camera-height", type=float, help="instead of --camera: camera height above the floor, m")
    parser.add_argument("--pitch", type=float, help="instead of --camera: degrees the camera looks down")
    parser.add_argument("--roll", type=float, help="with --pitch: camera roll in degrees (default 0)")
    add_lens_arguments(parser, "with --pitch", image_size_note)


def add_precision(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--precision", choices=PRECISIONS, default="fp32",
                        help="the network's arithmetic on the CPU: fp32 (default), or its hidden matrix products in "
                             "bf16 or int8 (faster; accuracy cost in docs/RESULTS.md)")


def add_lifting_arguments(parser: argparse.ArgumentParser, smooth_3d: str = OUTPUT_SMOOTHING,
                          live_smoothing: str | None = None) -> None:
    """The lifting flags. ``live_smoothing``: for ``ray3d live``, how its answers as they happen are smoothed
    (in words); there --smooth-2d, --smooth-3d, --flip-test and --no-refine shape only the world file, each
    person lifted again offline as they leave, and their help says so, and the world file is in the world frame
    (--frame world only)."""
    offline = " (world.csv only: each person lifted again as they leave)" if live_smoothing else ""
    parser.add_argument("--checkpoint", help="shipped model name or checkpoint path (default: ray3d for H36M-17 "
                        "keypoints, ray3d-real, trained for detectors, for any detector's layout and for videos)")
    add_precision(parser)
    parser.add_argument("--smooth-2d", choices=["savgol", "one-euro"], help=f"smooth the 2D input in time{offline}")
    parser.add_argument("--smooth-3d", choices=["savgol", "one-euro", "none"], default=smooth_3d,
                        help=f"smooth the 3D output in time (default {smooth_3d})" if not live_smoothing else
                        f"smooth world.csv's joints in time, each person lifted again as they leave (default "
                        f"{smooth_3d}); the answers as they happen (events, the page, MQTT, the store's positions) are "
                        f"always smoothed causally, {live_smoothing}")
    parser.add_argument("--flip-test", action="store_true",
                        help=f"average with the mirrored input's prediction{offline}")
    parser.add_argument("--no-refine", action="store_true",
                        help="keep the network's output: no track-level refinement (feet on the floor, one body size)"
                             + ("; world.csv only: the answers as they happen are always refined causally"
                                if live_smoothing else ""))
    parser.add_argument("--floor", help="a JSON file declaring floor regions (floor_regions: stages, platforms, "
                        "ramps; docs/floor.md) the refinement rests the feet on (default: the camera file's own, "
                        "else the plain floor z = 0)")
    parser.add_argument("--floor-z", type=float, metavar="M",
                        help="where the floor people stand on lies in the camera's frame, metres (0: at its z = 0; "
                             "default: the camera file's floor_z_m, else its z = 0 unless the people in view show it "
                             "off)")
    parser.add_argument("--no-floor-memory", action="store_true",
                        help="neither weigh in nor keep what the camera's people showed of its floor in earlier runs "
                             "(default: kept beside its camera file, CAMERA.floor.json, or in a live run's store)")
    if live_smoothing:
        parser.add_argument("--frame", choices=["world"], default="world",
                            help="frame of the output joints: world (z up, floor z = 0), the only one live writes")
    else:
        parser.add_argument("--frame", choices=["world", "camera"], default="world",
                            help="frame of the output joints: world (z up, floor z = 0; default) or camera (OpenCV: x "
                                 "right, y down, z forward, metres from the lens; .json, .csv and .npz)")


def add_time_buckets(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--every", type=duration, help="also count per time bucket of this length (e.g. 15min, "
                        "30s, 1h): by-time.csv and the report")
    parser.add_argument("--start-time", type=wall_clock, help="with --every: the video's first frame's date and time "
                        "(ISO 8601, e.g. 2026-12-05T08:00:00+01:00): the buckets in wall-clock time")


def duration(text: str) -> float:
    """``--every``'s value (``temporal.parse_duration``) -> seconds."""
    from ray3d.temporal import parse_duration

    try:
        return parse_duration(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def until(text: str) -> float:
    """``--until``'s value: a duration (``8h``, ``30min``) or a date and time (ISO 8601) -> seconds from now."""
    import datetime

    try:
        return duration(text)
    except argparse.ArgumentTypeError:
        pass
    try:
        moment = datetime.datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither a duration (8h, 30min, 90s) nor an ISO 8601 date and "
                                         "time (2026-12-07T08:00:00)") from None
    now = datetime.datetime.now(moment.tzinfo)
    return (moment - now).total_seconds()


def wall_clock(text: str):
    import datetime

    try:
        return datetime.datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an ISO 8601 date and time (2026-12-05T08:00:00)") from None


def job_from_args(args: argparse.Namespace, inputs: list, plural: str, singular: str):
    """The ``ray3d.jobs.Job`` a command's arguments ask for: ``inputs`` (``plural`` / ``singular`` name them in a
    refusal), each with its ``--camera`` (one each where there are several; a single input may have none: its
    camera then comes from --camera-height / --pitch), and every lifting, video and output option given."""
    from ray3d.errors import InputError
    from ray3d.jobs import CameraChoice, Job
    from ray3d.lifting.options import LiftOptions, VideoOptions

    given = args.camera or []
    given = [given] if isinstance(given, str) else given
    if (len(inputs) > 1 or len(given) > 1) and len(given) != len(inputs):
        raise InputError(f"--camera: {len(given)} given for {len(inputs)} {plural}; give one per {singular}, in order")
    cameras = tuple(CameraChoice(file, args.camera_height, args.pitch, args.image_size, args.roll, args.focal,
                                 args.hfov) for file in (given or [None] * len(inputs)))
    keypoints = not hasattr(args, "detector")
    video = VideoOptions() if keypoints else VideoOptions(
        args.fps, getattr(args, "start", 0), getattr(args, "frames", None), args.max_gap, args.min_track,
        getattr(args, "rejoin", 3.0))
    return Job(tuple(inputs), cameras, args.checkpoint, args.precision,
               LiftOptions(args.smooth_2d, args.smooth_3d, args.flip_test, not args.no_refine, args.frame,
                           floor_z=getattr(args, "floor_z", None)),
               args.floor, layout=getattr(args, "layout", None), fps=args.fps if keypoints else None,
               read_options={k: getattr(args, k) for k in ("subject", "action", "camera_index")
                             if getattr(args, k, None) is not None},
               detector=getattr(args, "detector", None), video=video, world_format=getattr(args, "format", ".json"),
               overlay=not (getattr(args, "no_overlay", False) or getattr(args, "privacy", False)),
               find_offsets=getattr(args, "find_offsets", False), overwrite=getattr(args, "force", False),
               site=getattr(args, "site", None), every_s=getattr(args, "every", None),
               start_time=getattr(args, "start_time", None),
               remember_floor=not getattr(args, "no_floor_memory", False))


def parse_offsets(text: str | None) -> list[float] | None:
    """``--offsets``: seconds separated by commas (None where not given)."""
    from ray3d.errors import InputError

    if not text:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--offsets: expected seconds separated by commas, got {text!r}") from None
