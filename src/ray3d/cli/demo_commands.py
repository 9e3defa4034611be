"""``ray3d demo``: the main job on a bundled clip (``ray3d.demo``)."""

from __future__ import annotations

import argparse


def demo(args: argparse.Namespace) -> int:
    from ray3d.demo import format_report, run_demo

    print(format_report(run_demo(args.out, args.checkpoint, frames=args.frames)))
    return 0
