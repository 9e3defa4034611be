"""A world's tracks on a site, written out: the events (``ray3d.site.events``), the tables of
``ray3d.site.analytics``, the floor plan and occupancy plots, the 3D viewer and the HTML report, in one folder.
What ``ray3d site``, ``ray3d video --site``, ``ray3d live`` with a site and batch inputs with a site write."""

from __future__ import annotations

from pathlib import Path

PLOTS = ("floor-plan.png", "occupancy.png")
PAGES = ("report.html", "viewer.html")
PRIVACY = ("Written from the world file's skeletons and tracks only: no image, crop or overlay of the video is in "
           "this report.")
CELL_M = 0.5  # the heat map's squares


BY_TIME = "by-time.csv"  # with ``every_s``: the counts per time bucket


def site_outputs(out_dir: str | Path, by_time: bool = False) -> list[Path]:
    """Every file ``analyse_site`` writes in ``out_dir`` (``by_time``: with time buckets)."""
    from ray3d.site.files import SITE_TABLES

    return [Path(out_dir) / name for name in (*PAGES, *SITE_TABLES, *PLOTS, *((BY_TIME,) if by_time else ()))]


def analyse_site(world, site, out_dir: str | Path, title: str = "ray3d site report", overwrite: bool = False,
                 every_s: float | None = None, start_time=None) -> tuple[list[dict], list[dict], list[Path]]:
    """A ``World``'s tracks on a ``Site``: the events, the per-place summaries and the files written in
    ``out_dir`` (``site_outputs``: the report, the viewer, every table and both plots; with ``every_s``, the
    counts per bucket of that many seconds in ``by-time.csv`` and the report, wall-clock from ``start_time``, a
    ``datetime``, when given)."""
    from ray3d.site.analytics import by_time, heat_map, person_frames, track_summaries, zone_summaries
    from ray3d.site.events import EVENT_KINDS, replay_site
    from ray3d.site.files import write_csv, write_site_tables
    from ray3d.viz.html_viewer import write_viewer
    from ray3d.viz.plots import plot_floor_plan, plot_occupancy
    from ray3d.viz.site_report import write_site_report

    out_dir = Path(out_dir)
    world = world.in_frame("world")
    replay, frames = replay_site(world, site), person_frames(world, site)
    events, times, counts = replay.events, replay.times, replay.occupancy
    places = zone_summaries(events, site, world.rejoined)
    series = [{"time_s": round(float(t), 4), **{name: int(values[k]) for name, values in counts.items()}}
              for k, t in enumerate(times)]
    tables = write_site_tables(out_dir, events, track_summaries(world, site, replay.time_in_zones), places, frames,
                               series, overwrite)
    buckets = None
    if every_s is not None:
        end_s = max(float(r.frames[-1]) / r.fps for r in world.tracks.values())
        buckets = by_time(events, times, counts, site, every_s, end_s, start_time)
        tables.append(write_csv(out_dir / BY_TIME, buckets, overwrite))
    heat, corner = heat_map(frames, world.fps, CELL_M)
    floor_plan = plot_floor_plan(site, frames, heat, corner, CELL_M, out_dir / PLOTS[0], overwrite)
    people = plot_occupancy(times, counts, out_dir / PLOTS[1], overwrite)
    viewer = write_viewer(out_dir / PAGES[1], world.tracks, world.fps, world.camera, title=f"{title}: every track",
                          overwrite=overwrite, more_cameras=world.cameras[1:])
    report = write_site_report(out_dir / PAGES[0], events, places, floor_plan, people, world.fps,
                               {kind.name: kind.colour for kind in EVENT_KINDS.values()}, title=title, note=PRIVACY,
                               overwrite=overwrite, buckets=buckets)
    return events, places, [report, viewer, *tables, floor_plan, people]
