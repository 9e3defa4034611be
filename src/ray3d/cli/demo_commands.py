"""``ray3d demo``: the main job on a bundled clip (``ray3d.demo``)."""

from __future__ import annotations

import argparse
from pathlib import Path


def demo(args: argparse.Namespace) -> int:
    from ray3d.demo import format_report, run_demo

    print(format_report(run_demo(args.out, args.checkpoint, frames=args.frames)))
    return 0


def add_parser(commands) -> None:
    """``ray3d demo``'s flags, bound to ``demo``."""
    demo_parser = commands.add_parser("demo", help="the main job: lift a bundled clip, compare with the truth and "
                                            "the baselines, write an HTML viewer and a GIF")
    demo_parser.add_argument("--out", type=Path, default=Path("ray3d-demo"), help="output folder (default ray3d-demo)")
    demo_parser.add_argument("--checkpoint", default="ray3d", help="model to demonstrate (default: the shipped Ray3D)")
    demo_parser.add_argument("--frames", type=int, help="use only the first N frames")
    demo_parser.set_defaults(handler=demo)
