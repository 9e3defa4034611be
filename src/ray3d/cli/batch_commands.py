"""``ray3d batch``: every input of a manifest, each one task on Ray (``ray3d.batch``)."""

from __future__ import annotations

import argparse
import sys


def batch(args: argparse.Namespace) -> int:
    from ray3d.batch import run

    report = run(args.manifest, args.out, args.address, args.workers, args.retries, args.cpus_per_task,
                 args.gpus_per_task)
    counts = {status: sum(r.status == status for r in report.reports) for status in ("done", "skipped", "failed")}
    print(f"{len(report.reports)} inputs: {counts['done']} done, {counts['skipped']} skipped (up to date), "
          f"{counts['failed']} failed -> {args.out} (summary: {report.summary})")
    for failure in report.failed:
        print(f"  failed: {failure.name} ({failure.input}): {failure.error}", file=sys.stderr)
    if report.failed:
        print(f"error: {len(report.failed)} of {len(report.reports)} inputs failed", file=sys.stderr)
        return 1
    return 0
