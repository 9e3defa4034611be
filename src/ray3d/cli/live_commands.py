"""``ray3d live``: a camera stream followed as it arrives (``ray3d.jobs.live``): events as JSON lines on
stdout and in OUT/events.jsonl, the world file OUT/world.csv growing as people leave, a page on localhost.
Several streams, one per calibrated camera: one world (``ray3d.fusion.live``), each camera's world file in
OUT/camera<k>_<name>/, fused into OUT/world.json at the end. With --address, each camera runs in a Ray actor
(``ray3d.live.cluster``); the outputs are the same.

Every event, each person's position once a second and each person's summary go to the site's store as they happen
(OUT/site.db, or --store); a run started again on the same store appends to it (a file is taken up where it was
left). A network stream that stalls or breaks off is opened again (--reconnect-max), its gap recorded.

Exit codes: 0 the stream ended, or --until came; 3 it stalled (no frame for --stall-timeout seconds); 4 it broke off
(3 and 4: files, or streams with --reconnect-max 0); 130 / 143 stopped by SIGINT (Ctrl-C) / SIGTERM; 2 bad input
(not a video, a bad camera, site or store). Every output is complete in each case."""

from __future__ import annotations

import argparse
import sys
import threading

EXIT_CODES = {"ended": 0, "until": 0, "stalled": 3, "broke off": 4}


def live(args: argparse.Namespace) -> int:
    import numpy as np

    from ray3d.cli.arguments import job_from_args
    from ray3d.cli.fusion_commands import parse_offsets
    from ray3d.io.site_files import read_site
    from ray3d.jobs.live import open_live, run_live_job, start_record
    from ray3d.live.mqtt import MqttPublisher
    from ray3d.live.runner import LiveOptions, stop_on_signals
    from ray3d.site.places import Site

    plan = read_site(args.site) if args.site else None
    job = job_from_args(args, args.source, "sources", "source")
    offsets = parse_offsets(args.offsets)
    if args.start_time is not None and args.every is None:
        from ray3d.errors import InputError

        raise InputError("--start-time: it places the time buckets of --every; give --every too")
    if args.until is not None and not args.until > 0:
        from ray3d.errors import InputError

        raise InputError(f"--until: {args.until:g} s from now: that moment has passed")
    mqtt = MqttPublisher(args.mqtt, plan or Site()) if args.mqtt else None
    try:
        recorder = start_record(job, args.store or args.out / "site.db", " ".join(sys.argv), plan, args.start_time)
    except BaseException:
        if mqtt is not None:
            mqtt.close(wait_s=0.0)
        raise
    try:
        inputs = open_live(job, False if args.unpaced else None, args.stall_timeout, args.address, args.workers,
                           recorder=recorder, reconnect_max_s=args.reconnect_max or None)
    except BaseException:
        recorder.discard()
        if mqtt is not None:
            mqtt.close(wait_s=0.0)
        raise
    taken_up = [f"{r.source} at frame {r.first_index}" for r in recorder.resumes if r.first_index]
    print(f"store {recorder.shown}: run {recorder.run}" + (f", taking up {', '.join(taken_up)}" if taken_up else ""),
          file=sys.stderr, flush=True)
    if inputs.on_ray:
        print(f"on Ray ({args.address}): {len(job.inputs)} camera actor(s), each reading and decoding its stream, "
              "finding and lifting its people", file=sys.stderr, flush=True)
    stop = threading.Event()
    caught = stop_on_signals(stop, inputs.followed)
    options = LiveOptions(not args.no_page, args.host, args.port, args.token, args.webhook,
                          None if args.quiet else sys.stdout, every_s=args.every, start_time=args.start_time,
                          until_s=args.until)
    try:
        summary = run_live_job(job, inputs, args.out, plan, options, stop,
                               started=lambda url: print(f"live page: {url}", file=sys.stderr, flush=True),
                               offsets_s=offsets, recorder=recorder, mqtt=mqtt)
    finally:
        recorder.close("not started")  # where the run failed before its stream: its end noted
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
    if mqtt is not None:
        print(f"mqtt: {mqtt.published} events published, {mqtt.dropped} messages dropped", file=sys.stderr)
    if summary.webhook:
        print(f"webhook: {summary.webhook['delivered']} delivered, {summary.webhook['failed']} failed, "
              f"{summary.webhook['dropped']} dropped", file=sys.stderr)
    if caught:
        return 128 + caught[0]
    return EXIT_CODES[summary.ending]
