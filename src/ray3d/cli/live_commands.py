"""``ray3d live``: a camera stream followed as it arrives (``ray3d.jobs.live``): events as JSON lines on
stdout and in OUT/events.jsonl, the world file OUT/world.csv growing as people leave, a page on localhost.
Several streams, one per calibrated camera: one world (``ray3d.fusion.live``), each camera's world file in
OUT/camera<k>_<name>/, fused into OUT/world.json at the end. With --address, each camera runs in a Ray actor
(``ray3d.live.cluster``); the outputs are the same.

Every event, each person's position once a second and each person's summary go to the site's store as they happen
(OUT/site.db, or --store); a run started again on the same store appends to it (a file is taken up where it was
left) and first ends the people a killed run left in view; one run writes a store at a time (a second is refused,
exit 2, naming the first). A network stream that stalls or breaks off is opened again (--reconnect-max), its gap
recorded.

Exit codes: 0 the stream ended, or --until came; 3 it stalled (no frame for --stall-timeout seconds); 4 it broke off
(3 and 4: files, or streams with --reconnect-max 0); 130 / 143 stopped by SIGINT (Ctrl-C) / SIGTERM; 2 bad input
(not a video, a bad camera, site or store, or the store written by another run now). Every output is complete in
each case."""

from __future__ import annotations

import argparse
import functools
import sys

EXIT_CODES = {"ended": 0, "until": 0, "stalled": 3, "broke off": 4}


def live(args: argparse.Namespace) -> int:
    from ray3d.cli.arguments import job_from_args, parse_offsets
    from ray3d.cli.printing import known_cameras, print_site_doubts
    from ray3d.errors import InputError
    from ray3d.jobs.live import live_job, open_live
    from ray3d.live.runner import LiveOptions

    if not args.source:
        raise InputError("give a stream (a file, a device number or a URL), or cameras in a --config file",
                         ("source",))
    if args.out is None:
        raise InputError("give the folder for the outputs (out)", ("out",))
    job = job_from_args(args, args.source, "sources", "source")
    if job.site is not None:  # a site drawn in pixels would count nobody, for ever
        print_site_doubts(job.site, job.site_plan(), known_cameras(job))
    if args.until is not None and not args.until > 0:
        raise InputError(f"--until: {args.until:g} s from now: that moment has passed")
    options = LiveOptions(not args.no_page, args.host, args.port, args.token, args.webhook,
                          None if args.quiet else sys.stdout, every_s=args.every, start_time=args.start_time,
                          until_s=args.until)
    streams = functools.partial(open_live, paced=False if args.unpaced else None, stall_timeout_s=args.stall_timeout,
                                address=args.address, workers=args.workers, reconnect_max_s=args.reconnect_max or None)
    run = live_job(job, args.out, options, streams, store=args.store or args.out / "site.db", mqtt=args.mqtt,
                   offsets_s=parse_offsets(args.offsets), command=" ".join(sys.argv), said=_said, signals=True)
    _print_run(run, args.site)
    return 128 + run.signal if run.signal else EXIT_CODES[run.summary.ending]


def _said(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _print_run(run, site_file) -> None:
    """How a live run went (``jobs.live.LiveRun``), on stderr: the frames, the latency, the events and the people;
    the rows its store was given; where its site report is; MQTT's and the webhook's counts."""
    import numpy as np

    summary, recorder = run.summary, run.recorder
    latency = summary.latency_ms
    print(f"{summary.why}: {summary.processed} of {summary.read} frames processed ({summary.dropped} dropped, "
          f"{100 * summary.dropped / max(summary.read, 1):.1f} %; {summary.postponed} people left for the next "
          f"frame to keep up); latency median "
          f"{np.median(latency) if len(latency) else float('nan'):.0f} ms, 99th percentile "
          f"{np.percentile(latency, 99) if len(latency) else float('nan'):.0f} ms; {summary.events} events; "
          f"{summary.tracks} people in {summary.files['world']} ({len(summary.left_out)} short tracks left out)",
          file=sys.stderr)
    print(f"store {recorder.shown}: run {recorder.run}: {recorder.written['events']} events, "
          f"{recorder.written['positions']} positions, {recorder.written['people']} people, "
          f"{recorder.written['gaps']} gaps written" + (f"; {recorder.lost} rows lost" if recorder.lost else ""),
          file=sys.stderr)
    if "site" in summary.files:
        print(f"site report of run {recorder.run} only: {summary.files['site']}; over every run: ray3d site --store "
              f"{recorder.shown} --site {site_file} --out REPORT", file=sys.stderr)
    if run.mqtt is not None:
        print(f"mqtt: {run.mqtt.published} events published, {run.mqtt.dropped} messages dropped", file=sys.stderr)
    if summary.webhook:
        print(f"webhook: {summary.webhook['delivered']} delivered, {summary.webhook['failed']} failed, "
              f"{summary.webhook['dropped']} dropped", file=sys.stderr)
