"""``ray3d demo``: the main job on a bundled clip (``ray3d.demo``)."""

from __future__ import annotations

import argparse

from ray3d.cli.arguments import add_command


def demo(args: argparse.Namespace) -> int:
    from ray3d.demo import format_report, run_demo

    print(format_report(run_demo(args.out, args.checkpoint, frames=args.frames)))
    return 0


def add_parser(commands) -> None:
    """``ray3d demo``'s flags, bound to ``demo``."""
    add_command(commands, "demo", demo, "the main job: lift a bundled clip, compare with the truth and the baselines, "
                "write an HTML viewer and a GIF")
