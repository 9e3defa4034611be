"""``ray3d site``: a world file's tracks on a site's zones and lines, as tables (``ray3d.site``)."""

from __future__ import annotations

import argparse

from ray3d.io.atomic import check_output, refuse_existing


def site(args: argparse.Namespace) -> int:
    from ray3d.io.site_files import SITE_TABLES, read_site, write_site_tables
    from ray3d.io.world import read_world
    from ray3d.site import site_events, track_summaries, zone_summaries

    for name in SITE_TABLES:  # refused before any work, not after it
        refuse_existing(check_output(args.out / name, (args.world, args.site)), args.force)
    plan, world = read_site(args.site), read_world(args.world)
    events = site_events(world, plan)
    places = zone_summaries(events, plan)
    paths = write_site_tables(args.out, events, track_summaries(world, plan), places, args.force)
    for row in places:
        counts = (f"{row['entries']} entries, {row['exits']} exits" if row["kind"] == "zone"
                  else f"{row['forward']} forward, {row['back']} back")
        print(f"{row['kind']} {row['place']}: {counts}")
    print(f"{len(events)} events of {len(world.tracks)} tracks -> {', '.join(str(p) for p in paths)}")
    return 0
