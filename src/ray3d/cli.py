"""The ``ray3d`` command line: a thin layer of argparse over the library; every command is a library call."""

from __future__ import annotations

import argparse
import sys

import ray3d
from ray3d.errors import InputError


def _demo(args: argparse.Namespace) -> int:
    from ray3d.smoke import geometry_report

    print(geometry_report())
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ray3d", description="Absolute 3D human pose in world coordinates from one calibrated camera.")
    parser.add_argument("--version", action="version", version=f"ray3d {ray3d.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = commands.add_parser(
        "demo", help="the main job (for now: a geometry check of every bundled Human3.6M camera)")
    demo.set_defaults(handler=_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return args.handler(args)
    except InputError as err:
        print(f"ray3d {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
