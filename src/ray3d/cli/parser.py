"""The ``ray3d`` argument parser: the top level; each subcommand's flags are added by its handler's module
(``add_parser``), bound to its handler there."""

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

# In the order ``ray3d --help`` lists them.
COMMAND_MODULES = (demo_commands, batch_commands, viz_commands, calibrate_commands, data_commands, model_commands,
                   lift_commands, video_commands, live_commands, site_commands, bench_commands)


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
    subcommands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMAND_MODULES:
        module.add_parser(subcommands)
    return parser


def subcommand_parser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    """The parser of the subcommand ``name`` of ``build_parser()``'s ``parser``."""
    subcommands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return subcommands.choices[name]
