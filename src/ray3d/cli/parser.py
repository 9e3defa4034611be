"""The ``ray3d`` argument parser: each command (``cli/flags.toml``'s ``[commands]``: its line in the help; its
own table: its flags) bound to its handler (``handlers()``)."""

from __future__ import annotations

import argparse

import ray3d
from ray3d.cli import (
    batch_commands,
    bench_commands,
    calibrate_commands,
    data_commands,
    demo_commands,
    lift_commands,
    live_commands,
    model_commands,
    site_commands,
    video_commands,
    viz_commands,
)
from ray3d.cli.arguments import add_flags, flag_table


def handlers() -> dict:
    """Each command's handler (a group's, data and bench: each of its commands'), in the order ``ray3d --help`` lists
    them; looked up as each parser is built, so that a handler replaced in its module is the one called."""
    return {
        "demo": demo_commands.demo, "batch": batch_commands.batch, "viz": viz_commands.viz,
        "calibrate": calibrate_commands.calibrate,
        "data": {"info": data_commands.data_info, "import-bvh": data_commands.import_bvh,
                 "import-amc": data_commands.import_amc, "cameras": data_commands.cameras,
                 "samples-speed": data_commands.samples_speed},
        "train": model_commands.train, "evaluate": model_commands.evaluate, "models": model_commands.models,
        "export": model_commands.export, "lift": lift_commands.lift, "fuse": lift_commands.fuse,
        "video": video_commands.video, "live": live_commands.live, "site": site_commands.site,
        "bench": {"robustness": bench_commands.robustness, "calibration": bench_commands.calibration,
                  "real-video": bench_commands.real_video, "real-near": bench_commands.real_near,
                  "level": bench_commands.level, "speed": bench_commands.speed, "identity": bench_commands.identity,
                  "people": bench_commands.people, "live": bench_commands.live, "fusion": bench_commands.fusion,
                  "worlds": bench_commands.worlds}}


class OneLineErrors(argparse.ArgumentParser):
    """A parser whose errors are one line (not the usage block), worded as the other refusals are
    (``ray3d lift: error: ...``): bad input is one line and exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineErrors(
        prog="ray3d", description="Absolute 3D human pose in world coordinates from one calibrated camera.")
    parser.add_argument("--version", action="version", version=f"ray3d {ray3d.__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    _add_commands(parser, handlers())
    return parser


def _add_commands(parser: argparse.ArgumentParser, handlers: dict, group: str = "") -> None:
    """``handlers``' commands under ``parser`` (those of ``group``: ``ray3d GROUP COMMAND``, one of them required)."""
    subcommands = parser.add_subparsers(dest=f"{group}_command" if group else "command",
                                        metavar=f"{group.upper()}_COMMAND" if group else "COMMAND",
                                        required=bool(group))
    for name, handler in handlers.items():
        table = f"{group}.{name}" if group else name
        command = subcommands.add_parser(name, help=flag_table("commands")[table])
        if isinstance(handler, dict):
            _add_commands(command, handler, name)
        else:
            add_flags(command, table)
            command.set_defaults(handler=handler)


def subcommand_parser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    """The parser of the subcommand ``name`` of ``build_parser()``'s ``parser``."""
    subcommands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return subcommands.choices[name]
