"""Every command's flags: declared as data in ``flags.toml`` and added to a parser by ``add_flags``, with the
converters their values go through; and reading the shared ones back into what the library takes."""

from __future__ import annotations

import argparse
import datetime
import functools
import re
import tomllib
from pathlib import Path

from ray3d.errors import InputError
from ray3d.models.precision import PRECISIONS
from ray3d.temporal import OUTPUT_SMOOTHING, parse_duration

FLAGS_FILE = Path(__file__).with_name("flags.toml")
SHARED = "shared."  # a key naming a table of shared flags, added where it stands
KEYWORDS = {"help", "default", "required", "action", "nargs", "metavar", "choices", "dest", "type"}
# "{NAME}" or "{NAME:FORMAT}" in flags.toml: a named value or a word.
PLACEHOLDER = re.compile(r"\{(\w+)(?::([^{}]*))?\}")


@functools.cache
def flag_file() -> dict:
    with FLAGS_FILE.open("rb") as file:
        return tomllib.load(file)


def flag_table(name: str) -> dict:
    """The flags of flags.toml's table ``name`` (``"bench.level"``), in the file's order."""
    table = flag_file()
    for part in name.split("."):
        table = table[part]
    return table


def named_values() -> dict:
    """The constants flags.toml names by "{NAME}": defaults, choices and help texts kept where their concept is."""
    # Read only when a parser is built: these modules bring torch and the video stack.
    from ray3d.body import ADULT_STATURE_M
    from ray3d.checkpoints import DETECTOR_MODEL
    from ray3d.data.virtual_cameras import SET_NAMES
    from ray3d.io.world import WRITTEN_FORMATS
    from ray3d.live.people import LIVE_SMOOTHING
    from ray3d.video.detectors import DEFAULT_DETECTOR, DETECTOR_HELP

    return {"ADULT_STATURE_M": ADULT_STATURE_M, "DETECTOR_MODEL": DETECTOR_MODEL, "SET_NAMES": SET_NAMES,
            "SET_NAMES_LISTED": ", ".join(SET_NAMES), "WRITTEN_FORMATS": WRITTEN_FORMATS,
            "DEFAULT_DETECTOR": DEFAULT_DETECTOR, "DETECTOR_HELP": DETECTOR_HELP, "PRECISIONS": PRECISIONS,
            "OUTPUT_SMOOTHING": OUTPUT_SMOOTHING, "LIVE_MIN_CUTOFF_HZ": LIVE_SMOOTHING[0],
            "LIVE_BETA": LIVE_SMOOTHING[1]}


def add_flags(parser: argparse.ArgumentParser, table: str) -> None:
    """Adds the flags of flags.toml's ``table`` to ``parser`` in the file's order."""
    _add_table(parser, table, named_values())


def _add_table(parser: argparse.ArgumentParser, table: str, names: dict) -> None:
    for name, spec in flag_table(table).items():
        if name.startswith(SHARED):
            _add_table(parser, name, {**names, **{word: filled(text, names) for word, text in spec.items()}})
        else:
            parser.add_argument(name, **flag_keywords(spec, names))


def flag_keywords(spec: dict, names: dict) -> dict:
    """argparse's keywords for one flag of flags.toml: its placeholders filled, its type a converter."""
    unknown = set(spec) - KEYWORDS
    if unknown:
        raise ValueError(f"{FLAGS_FILE.name}: {', '.join(sorted(unknown))}: not an argparse keyword here")
    keywords = {key: filled(value, names) for key, value in spec.items()}
    if "type" in keywords:
        if keywords["type"] not in CONVERTERS:
            raise ValueError(f"{FLAGS_FILE.name}: type {keywords['type']}: not one of {', '.join(CONVERTERS)}")
        keywords["type"] = CONVERTERS[keywords["type"]]
        if isinstance(keywords.get("default"), str):  # as argparse reads a default given as text
            keywords["default"] = keywords["type"](keywords["default"])
    return keywords


def filled(value, names: dict):
    """A value of flags.toml with its placeholders filled from ``names``: a value that is one placeholder is the
    named value itself (a tuple, a number); in a text, each is written in."""
    if isinstance(value, list):
        return [filled(item, names) for item in value]
    if not isinstance(value, str):
        return value
    unknown = {match[1] for match in PLACEHOLDER.finditer(value)} - set(names)
    if unknown:
        raise ValueError(f"{FLAGS_FILE.name}: {', '.join(sorted(unknown))}: not a named value or a word given here")
    whole = PLACEHOLDER.fullmatch(value)
    if whole and whole[2] is None:
        return names[whole[1]]
    return PLACEHOLDER.sub(lambda match: format(names[match[1]], match[2] or ""), value)


def duration(text: str) -> float:
    """``--every``'s value (``temporal.parse_duration``) -> seconds."""
    try:
        return parse_duration(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def until(text: str) -> float:
    """``--until``'s value: a duration (``8h``, ``30min``) or a date and time (ISO 8601) -> seconds from now."""
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
    try:
        return datetime.datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an ISO 8601 date and time (2026-12-05T08:00:00)") from None


# The converters flags.toml's "type" names.
CONVERTERS = {"int": int, "float": float, "str": str, "path": Path, "duration": duration, "until": until,
              "wall_clock": wall_clock}


def job_from_args(args: argparse.Namespace, inputs: list, plural: str, singular: str):
    """The ``ray3d.jobs.Job`` a command's arguments ask for: ``inputs`` (``plural`` / ``singular`` name them in a
    refusal), each with its ``--camera`` (one each where there are several; a single input may have none: its
    camera then comes from --camera-height / --pitch), and every lifting, video and output option given."""
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
    if not text:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--offsets: expected seconds separated by commas, got {text!r}") from None
