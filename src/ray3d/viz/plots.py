"""Plots: metric curves (one line per method against a swept variable, as the paper's robustness figures), and a
site's floor plan and zone occupancy."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ray3d.io.atomic import atomic_path  # noqa: E402


def plot_sweep_panels(x: list[float], panels: dict[str, dict[str, list[float]]], xlabel: str, title: str,
                      path: str | Path) -> Path:
    """One PNG with a panel per metric ({y-axis label: {method: values}}), one line per method."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), dpi=110, squeeze=False)
    for axis, (ylabel, curves) in zip(axes[0], panels.items()):
        for name, values in curves.items():
            axis.plot(x, values, marker="o", ms=3, label=name)
        axis.set_xlabel(xlabel)
        axis.set_ylabel(ylabel)
        axis.grid(alpha=0.3)
        axis.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path, overwrite=True)


def plot_sweep(x: list[float], curves: dict[str, list[float]], xlabel: str, ylabel: str, title: str,
               path: str | Path) -> Path:
    """A single-panel sweep plot."""
    return plot_sweep_panels(x, {ylabel: curves}, xlabel, title, path)


def _save(fig, path: str | Path, overwrite: bool) -> Path:
    path = Path(path)
    with atomic_path(path, overwrite=overwrite) as temporary:
        fig.savefig(temporary, format="png")
    plt.close(fig)
    return path


def plot_floor_plan(site, rows: list[dict], heat, corner: tuple[float, float], cell_m: float, path: str | Path,
                    overwrite: bool = False) -> Path:
    """The floor plan (metres, seen from above) over the site's picture of the floor if it has one: time spent per
    square (``ray3d.site.heat_map``), everybody's path, the site's zones and its directed lines (an arrow points from a
    line's left to its right: "forward")."""
    fig, axis = plt.subplots(figsize=(7.5, 6.5), dpi=110)
    if site.floor_plan is not None:
        axis.imshow(site.floor_plan.image, extent=site.floor_plan.extent(), zorder=0)
    if heat.size:
        extent = (corner[0], corner[0] + heat.shape[1] * cell_m, corner[1], corner[1] + heat.shape[0] * cell_m)
        image = axis.imshow(np.ma.masked_equal(heat, 0), origin="lower", extent=extent, cmap="Oranges", alpha=0.8)
        fig.colorbar(image, ax=axis, label=f"seconds spent per {cell_m:g} m square")
    for track in dict.fromkeys(row["track"] for row in rows):
        xy = np.array([[row["x_m"], row["y_m"]] for row in rows if row["track"] == track])
        axis.plot(xy[:, 0], xy[:, 1], lw=0.8, alpha=0.6)
    for zone in site.zones:
        closed = np.vstack([zone.polygon, zone.polygon[:1]])
        axis.plot(closed[:, 0], closed[:, 1], color="tab:blue", lw=2)
        axis.text(*zone.polygon.mean(axis=0), zone.name, color="tab:blue", ha="center")
    for line in site.lines:
        axis.plot(*np.stack([line.start, line.end]).T, color="tab:red", lw=2.5)
        middle, direction = (line.start + line.end) / 2, line.end - line.start
        right = np.array([direction[1], -direction[0]]) / np.linalg.norm(direction) * 0.5
        axis.annotate("", middle + right, middle, arrowprops={"arrowstyle": "->", "color": "tab:red"})
        axis.text(*(line.end + 0.1), line.name, color="tab:red")
    axis.set_aspect("equal")
    axis.set_xlabel("x (m)")
    axis.set_ylabel("y (m)")
    axis.set_title("floor plan: paths, time spent, zones and lines (arrow: forward)")
    axis.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path, overwrite)


def plot_occupancy(times, counts: dict, path: str | Path, overwrite: bool = False) -> Path:
    """People in each zone over time."""
    fig, axis = plt.subplots(figsize=(8, 3.2), dpi=110)
    for name, values in counts.items():
        axis.step(times, values, where="post", label=name)
    axis.set_xlabel("time (s)")
    axis.set_ylabel("people in the zone")
    if counts:  # a site of lines only has no zone to count people in
        axis.legend(fontsize=8)
    axis.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path, overwrite)


def plot_by_time(rows: list[dict], site, gaps: list[tuple[float, float]], path: str | Path,
                 overwrite: bool = False, uncertain: list[tuple[float, float]] = ()) -> Path:
    """The counts per time bucket (``site.record.record_buckets`` rows) read at a glance: entries, exits and
    crossings per bucket (bars), each zone's mean and peak occupancy (lines), the record's gaps (Unix times)
    shaded on both, and the stretches whose counts are ``uncertain`` (a run falling behind) hatched in their own
    colour."""
    import datetime

    import matplotlib.dates as dates

    starts = [datetime.datetime.fromisoformat(row["start"]) for row in rows]
    ends = [datetime.datetime.fromisoformat(row["end"]) for row in rows]
    width = [(e - s).total_seconds() / 86400 for s, e in zip(starts, ends)]
    fig, (counts, people) = plt.subplots(2, 1, figsize=(10.5, 5.5), dpi=110, sharex=True)
    series = {"entries": [sum(row.get(f"{z.name}: entries", 0) for z in site.zones) for row in rows],
              "exits": [sum(row.get(f"{z.name}: exits", 0) for z in site.zones) for row in rows],
              "crossings": [sum(row.get(f"{line.name}: forward", 0) + row.get(f"{line.name}: back", 0)
                                for line in site.lines)
                            for row in rows]}
    shown = [(name, values) for name, values in series.items() if any(values)] or [("entries", series["entries"])]
    for k, (name, values) in enumerate(shown):
        offsets = [s + datetime.timedelta(days=w * k / len(shown)) for s, w in zip(starts, width)]
        counts.bar(offsets, values, width=[w / len(shown) for w in width], align="edge", label=name)
    counts.set_ylabel("per bucket")
    for zone in site.zones:
        middles = [s + (e - s) / 2 for s, e in zip(starts, ends)]
        line, = people.plot(middles, [row[f"{zone.name}: mean occupancy"] for row in rows], marker="o", ms=3,
                            label=f"{zone.name}: mean")
        people.plot(middles, [row[f"{zone.name}: peak occupancy"] for row in rows], ls=":", color=line.get_color(),
                    label=f"{zone.name}: peak")
    people.set_ylabel("people in the zone")
    if site.zones:
        people.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside: never on the data
    zone_of = starts[0].tzinfo if starts else None
    for k, (low, high) in enumerate(gaps):
        for axis in (counts, people):
            axis.axvspan(datetime.datetime.fromtimestamp(low, zone_of), datetime.datetime.fromtimestamp(high, zone_of),
                         color="0.6", alpha=0.35, lw=0, label="no record" if k == 0 and axis is counts else None)
    for k, (low, high) in enumerate(uncertain):
        for axis in (counts, people):
            axis.axvspan(datetime.datetime.fromtimestamp(low, zone_of), datetime.datetime.fromtimestamp(high, zone_of),
                         color="tab:orange", alpha=0.25, lw=0, hatch="//",
                         label="uncertain: could not keep up" if k == 0 and axis is counts else None)
    counts.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    people.xaxis.set_major_formatter(dates.ConciseDateFormatter(people.xaxis.get_major_locator(), tz=zone_of))
    for axis in (counts, people):
        axis.grid(alpha=0.3)
    counts.set_title("by time: counts per bucket, occupancy, gaps shaded" +
                     (", uncertain counts hatched" if len(uncertain) else ""))
    fig.tight_layout()
    return _save(fig, path, overwrite)
