"""``ray3d site``: a world file's tracks on a site's zones and lines, as tables (``ray3d.site``)."""

from __future__ import annotations

import argparse

from ray3d.io.atomic import check_output, refuse_existing


PLOTS = ("floor-plan.png", "occupancy.png")
CELL_M = 0.5


def site(args: argparse.Namespace) -> int:
    from ray3d.io.site_files import SITE_TABLES, read_site, write_site_tables
    from ray3d.io.world import read_world
    from ray3d.site import heat_map, occupancy, person_frames, site_events, track_summaries, zone_summaries
    from ray3d.viz.plots import plot_floor_plan, plot_occupancy

    for name in SITE_TABLES + PLOTS:  # refused before any work, not after it
        refuse_existing(check_output(args.out / name, (args.world, args.site)), args.force)
    plan, world = read_site(args.site), read_world(args.world)
    events, frames = site_events(world, plan), person_frames(world, plan)
    places = zone_summaries(events, plan)
    times, counts = occupancy(frames, plan, world.fps)
    series = [{"time_s": round(float(t), 4), **{name: int(values[k]) for name, values in counts.items()}}
              for k, t in enumerate(times)]
    paths = write_site_tables(args.out, events, track_summaries(world, plan), places, frames, series, args.force)
    heat, corner = heat_map(frames, world.fps, CELL_M)
    paths.append(plot_floor_plan(plan, frames, heat, corner, CELL_M, args.out / PLOTS[0], args.force))
    paths.append(plot_occupancy(times, counts, args.out / PLOTS[1], args.force))
    for row in places:
        tally = (f"{row['entries']} entries, {row['exits']} exits" if row["kind"] == "zone"
                 else f"{row['forward']} forward, {row['back']} back")
        print(f"{row['kind']} {row['place']}: {tally}")
    kinds = {}
    for event in events:
        kinds[event["event"]] = kinds.get(event["event"], 0) + 1
    print(f"{len(events)} events of {len(world.tracks)} tracks ({', '.join(f'{n} {k}' for k, n in kinds.items())}) "
          f"-> {args.out}: {', '.join(p.name for p in paths)}")
    return 0
