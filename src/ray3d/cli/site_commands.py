"""``ray3d site`` (and ``ray3d video --site``): a world's tracks on a site's zones and lines, as a report, tables
and plots (``ray3d.site.report.analyse_site``)."""

from __future__ import annotations

import argparse
import sys

from ray3d.cli.printing import print_ankle_plane, print_places, print_site_doubts, print_site_report
from ray3d.io.atomic import check_output, refuse_existing


def site(args: argparse.Namespace) -> int:
    from ray3d.errors import InputError
    from ray3d.io.world import read_world
    from ray3d.jobs import check_site_outputs, site_report
    from ray3d.site.files import read_site

    if (args.world is None) == (args.store is None):
        raise InputError("give a world file or --store (one of them)")
    if args.store is not None:
        return store_report(args, read_site)
    if args.from_time is not None or args.to_time is not None:
        raise InputError("--from / --to: they choose a period of a --store")
    check_site_outputs(args.out, (args.world, args.site), args.force, args.every)
    plan = read_site(args.site)  # a bad site file is refused before the world file is read
    world = read_world(args.world)
    print_ankle_plane(world.tracks, world.camera)  # where the people stand rests on it
    print_site_doubts(args.site, plan, world.cameras, world)  # a site drawn in pixels counts nobody
    print_site_report(site_report(world, plan, args.out, f"{args.world.name} on {args.site.name}", args.force,
                                  args.every, args.start_time), world)
    return 0


def store_report(args: argparse.Namespace, read_site) -> int:
    """``ray3d site --store``: the record over --from .. --to, and its gaps said."""
    from ray3d.errors import InputError
    from ray3d.site.record import analyse_record, record_outputs, unfollowed_places
    from ray3d.store import floor_decisions, read_record

    if args.start_time is not None:
        raise InputError("--start-time: a store's record carries its own clock; give --from / --to")
    if args.copy_to is not None:
        from ray3d.store import copy_record

        copied = copy_record(args.store, args.copy_to)
        print(f"copied to {args.copy_to.split('@')[-1]}: " + ", ".join(f"{n} {table}" for table, n in copied.items()))
    for path in record_outputs(args.out, args.every is not None):
        refuse_existing(check_output(path, (args.site,)), args.force)
    plan = read_site(args.site)
    low, high = (None if t is None else t.timestamp() for t in (args.from_time, args.to_time))
    if low is not None and high is not None and not high > low:
        raise InputError("--to: it must come after --from")
    record = read_record(args.store, low, high)
    for camera, plane in floor_decisions(args.store).items():  # where the people stand rests on it
        print(f"note: {plane.message(camera)}", file=sys.stderr)
    for line in unfollowed_places(record, plan):
        print(f"note: {line}", file=sys.stderr)
    places, paths = analyse_record(record, plan, args.out, args.every, f"{record.location} on {args.site.name}",
                                   args.force)
    print_places(places)
    down = sum(g["to_at"] - g["from_at"] for g in record.gaps)
    print(f"{len(record.events)} events of {len(record.people)} people over {len(record.runs)} run(s); "
          f"{len(record.gaps)} gap(s) in the record ({down:.1f} s) -> {args.out}: {', '.join(p.name for p in paths)}")
    return 0
