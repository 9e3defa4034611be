"""``ray3d live``: a camera stream followed as it arrives (``ray3d.jobs.live``): events as JSON lines on
stdout and in OUT/events.jsonl, the world file OUT/world.csv growing as people leave, a page on localhost.
Several streams, one per calibrated camera: one world (``ray3d.fusion.live``), each camera's world file in
OUT/camera<k>_<name>/, fused into OUT/world.json at the end. With --address, each camera runs in a Ray actor
(``ray3d.live.cluster``); the outputs are the same.

Exit codes: 0 the stream ended; 3 it stalled (no frame for --stall-timeout seconds); 4 it broke off; 130 / 143
stopped by SIGINT (Ctrl-C) / SIGTERM; 2 bad input (not a video, a bad camera or site file). Every output is
complete in each case."""

from __future__ import annotations

import argparse
import sys
import threading

EXIT_CODES = {"ended": 0, "stalled": 3, "broke off": 4}


def live(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.cli.arguments import job_from_args
    from ray3d.cli.fusion_commands import parse_offsets
    from ray3d.io.site_files import read_site
    from ray3d.jobs.live import open_live, run_live_job
    from ray3d.live.runner import LiveOptions, stop_on_signals

    plan = read_site(args.site) if args.site else None
    job = job_from_args(args, args.source, "sources", "source")
    offsets = parse_offsets(args.offsets)
    inputs = open_live(job, False if args.unpaced else None, args.stall_timeout, args.address, args.workers)
    if inputs.on_ray:
        print(f"on Ray ({args.address}): {len(job.inputs)} camera actor(s), each reading and decoding its stream, "
              "finding and lifting its people", file=sys.stderr, flush=True)
    stop = threading.Event()
    caught = stop_on_signals(stop, inputs.followed)
    if args.start_time is not None and args.every is None:
        from ray3d.errors import InputError

        raise InputError("--start-time: it places the time buckets of --every; give --every too")
    options = LiveOptions(not args.no_page, args.host, args.port, args.token, args.webhook,
                          None if args.quiet else sys.stdout, every_s=args.every, start_time=args.start_time)
    summary = run_live_job(job, inputs, args.out, plan, options, stop,
                           started=lambda url: print(f"live page: {url}", file=sys.stderr, flush=True),
                           offsets_s=offsets)
    latency = summary.latency_ms
    print(f"{summary.why}: {summary.processed} of {summary.read} frames processed ({summary.dropped} dropped, "
          f"{100 * summary.dropped / max(summary.read, 1):.1f} %; {summary.postponed} people left for the next "
          f"frame to keep up); latency median "
          f"{np.median(latency) if len(latency) else float('nan'):.0f} ms, 99th percentile "
          f"{np.percentile(latency, 99) if len(latency) else float('nan'):.0f} ms; {summary.events} events; "
          f"{summary.tracks} people in {summary.files['world']} ({len(summary.left_out)} short tracks left out)",
          file=sys.stderr)
    if summary.webhook:
        print(f"webhook: {summary.webhook['delivered']} delivered, {summary.webhook['failed']} failed, "
              f"{summary.webhook['dropped']} dropped", file=sys.stderr)
    if caught:
        return 128 + caught[0]
    return EXIT_CODES[summary.ending]
