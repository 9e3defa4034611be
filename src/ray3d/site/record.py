"""A site's stored record (``ray3d.store``) over any period, as a report: the counts per place, the events by kind,
the heat map of time spent and the counts per time bucket (entries, exits and crossings, occupancy; a chart with
the record's gaps shaded and the table beside it in consistently rounded figures), and where the record has gaps.
What ``ray3d site --store`` writes. The events are the ones the live runs found (the store holds them as they
happened), so the report over a store is the sum of its runs' events."""

from __future__ import annotations

import datetime
import json
from pathlib import Path

import numpy as np

from ray3d.site.analytics import TimeBuckets, heat_map, zone_summaries
from ray3d.site.places import Site, in_zones

CELL_M = 0.5  # the heat map's squares
PATHS_DRAWN = 200  # the floor plan draws the paths of this many people at most (the latest)
DOWN = "the service was down"
RECORD_FILES = ("report.html", "events.csv", "people.csv", "places.csv", "gaps.csv", "floor-plan.png")
BY_TIME_FILES = ("by-time.csv", "by-time.png")


def record_outputs(out_dir: str | Path, by_time: bool = False) -> list[Path]:
    """Every file ``analyse_record`` writes in ``out_dir`` (``by_time``: with time buckets)."""
    return [Path(out_dir) / name for name in (*RECORD_FILES, *(BY_TIME_FILES if by_time else ()))]


def unfollowed_places(record, site: Site) -> list[str]:
    """The site's zones and lines that no run of the record followed (the live runs' events are of the site file
    they were given): a line for each, saying that its counts are absent (its occupancy still comes from the
    positions)."""
    followed = {kind: set() for kind in ("zones", "lines")}
    for run in record.runs:
        document = json.loads(run["site"]) if run.get("site") else {}
        for kind in followed:
            followed[kind] |= {place["name"] for place in document.get(kind, ())}
    lines = [f"zone {zone.name!r}: no run of the record followed it; its entries and exits are not in it (its "
             "occupancy and heat map come from the positions)" for zone in site.zones if zone.name not in
             followed["zones"]]
    return lines + [f"line {line.name!r}: no run of the record followed it; its crossings are not in it"
                    for line in site.lines if line.name not in followed["lines"]]


def covered_seconds(record, seconds: np.ndarray) -> np.ndarray:
    """Which of ``seconds`` (Unix times) the record covers: inside a run's recorded span and not in a gap that
    left it blind (the service down, or the only camera of a run down). (N,) bool."""
    seconds = np.asarray(seconds, dtype=float)
    covered = np.zeros(len(seconds), dtype=bool)
    single = {run["run"] for run in record.runs if len(json.loads(run["sources"])) == 1}
    for run in record.runs:
        if run["first_at"] is not None and run["last_at"] is not None:
            covered |= (seconds >= run["first_at"]) & (seconds <= run["last_at"])
    for gap in record.gaps:
        if gap["why"] == DOWN or gap["run"] in single:
            covered &= ~((seconds > gap["from_at"]) & (seconds < gap["to_at"]))
    return covered


def uncertain_seconds(record, seconds: np.ndarray) -> np.ndarray:
    """Which of ``seconds`` (Unix times) fall in a stretch where a run could not keep up with a camera (frames
    dropped: its counts uncertain). (N,) bool."""
    seconds = np.asarray(seconds, dtype=float)
    uncertain = np.zeros(len(seconds), dtype=bool)
    for stretch in getattr(record, "behind", ()):
        uncertain |= (seconds >= stretch["from_at"]) & (seconds <= stretch["to_at"])
    return uncertain


def record_buckets(record, site: Site, every_s: float) -> list[dict]:
    """The counts per ``every_s`` bucket from the record's start (wall clock): each zone's entries, exits, mean
    dwell, mean and peak occupancy (over the seconds recorded), each line's crossings, the share of the
    bucket the record covers and the share of it whose counts are uncertain (a run falling behind). Buckets begin at
    multiples of ``every_s`` since 1970 (UTC): an hour's at the hour."""
    start = float(np.floor(record.from_at / every_s) * every_s)  # buckets on the clock's hours, days, ...
    buckets = TimeBuckets(site, every_s, datetime.datetime.fromtimestamp(start).astimezone())
    buckets.add([{**event, "time_s": event["at"] - start} for event in record.events])
    seconds = np.arange(np.floor(start), np.ceil(record.to_at))
    covered = covered_seconds(record, seconds + 0.5)
    uncertain = uncertain_seconds(record, seconds + 0.5) & covered
    positions = record.positions
    second_of = np.floor(positions["at"]).astype(np.int64)
    inside = in_zones(site, np.stack([positions["x"], positions["y"]], axis=-1))  # the monitor's rule, each second
    counts = {name: dict(zip(*(v.tolist() for v in np.unique(second_of[flags], return_counts=True))))
              for name, flags in inside.items()}
    for second in seconds[covered]:
        buckets.observe(float(second - start), {name: per.get(int(second), 0) for name, per in counts.items()})
    rows = buckets.rows(record.to_at - start)
    for row in rows:
        span = (seconds >= start + row["start_s"]) & (seconds < start + row["end_s"])
        row["recorded %"] = int(round(100 * covered[span].mean())) if span.any() else 0
        row["uncertain %"] = int(round(100 * uncertain[span].mean())) if span.any() else 0
    return [rounded(row) for row in rows]


def rounded(row: dict) -> dict:
    """A bucket's figures as the table shows them: counts whole, occupancy to 0.1, dwell to the second, times
    without their seconds' fractions."""
    out = {}
    for key, value in row.items():
        if key in ("start_s", "end_s"):
            continue
        if key in ("start", "end"):
            out[key] = datetime.datetime.fromisoformat(value).strftime("%Y-%m-%d %H:%M:%S")
        elif value is None:
            out[key] = None
        elif key.endswith("mean occupancy"):
            out[key] = round(float(value), 1)
        elif key.endswith("mean dwell s"):
            out[key] = int(round(float(value)))
        else:
            out[key] = value
    return out


def analyse_record(record, site: Site, out_dir: str | Path, every_s: float | None = None,
                   title: str = "ray3d site record", overwrite: bool = False) -> tuple[list[dict], list[Path]]:
    """A ``StoredRecord`` on a ``Site``: the per-place counts and the files written in ``out_dir``
    (``record_outputs``)."""
    from ray3d.site.files import write_csv
    from ray3d.viz.plots import plot_by_time, plot_floor_plan
    from ray3d.viz.site_report import write_record_report

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    joined = {p["person"]: p["rejoins"] for p in record.people if p["rejoins"]}
    places = zone_summaries(record.events, site, joined)
    events = [{"at": _clock(e["at"]), "run": e["run"], **{k: v for k, v in e.items() if k not in ("at", "run")}}
              for e in record.events]
    people = [{**p, "first_at": _clock(p["first_at"]), "last_at": _clock(p["last_at"])} for p in record.people]
    gaps = [{"camera": g["camera"], "from": _clock(g["from_at"]), "to": _clock(g["to_at"]),
             "seconds": round(g["to_at"] - g["from_at"], 1), "why": g["why"], "run": g["run"]} for g in record.gaps]
    paths = [out_dir / name for name in RECORD_FILES]
    tables = [write_csv(paths[1], events, overwrite), write_csv(paths[2], people, overwrite),
              write_csv(paths[3], places, overwrite), write_csv(paths[4], gaps, overwrite)]
    positions = record.positions
    rows = [{"track": person, "x_m": x, "y_m": y} for person, x, y in
            zip(positions["person"], positions["x"], positions["y"])]
    heat, corner = heat_map(rows, 1.0, CELL_M)  # one position per person-second
    drawn = set(list(dict.fromkeys(positions["person"][::-1]))[:PATHS_DRAWN])
    plan = plot_floor_plan(site, [r for r in rows if r["track"] in drawn], heat, corner, CELL_M, paths[5], overwrite)
    buckets, chart = None, None
    if every_s is not None:
        buckets = record_buckets(record, site, every_s)
        tables.append(write_csv(out_dir / BY_TIME_FILES[0], buckets, overwrite))
        chart = plot_by_time(buckets, site, [(g["from_at"], g["to_at"]) for g in record.gaps],
                             out_dir / BY_TIME_FILES[1], overwrite,
                             uncertain=[(b["from_at"], b["to_at"]) for b in getattr(record, "behind", ())])
    kinds: dict[str, int] = {}
    for event in record.events:
        kinds[event["event"]] = kinds.get(event["event"], 0) + 1
    report = write_record_report(paths[0], title, _summary(record), places, kinds, gaps, plan, chart, buckets,
                                 overwrite)
    return places, [report, *tables, plan, *([chart] if chart else [])]


def _clock(at: float) -> str:
    return datetime.datetime.fromtimestamp(float(at)).astimezone().isoformat(timespec="seconds")


def _summary(record) -> str:
    runs = {e["run"] for e in record.events} | {p["run"] for p in record.people}
    down = sum(g["to_at"] - g["from_at"] for g in record.gaps)
    behind = getattr(record, "behind", [])
    uncertain = "".join(
        f" Counts uncertain from {_clock(b['from_at'])} to {_clock(b['to_at'])}: the run could not keep up with "
        f"camera {b['camera']} (frames dropped or people left for the next frame; {100 * b['dropped_share']:.0f} % "
        "of its frames dropped)." for b in behind)
    return (f"From {_clock(record.from_at)} to {_clock(record.to_at)}: {len(record.events)} events of "
            f"{len(record.people)} people over {len(runs)} run(s); {len(record.gaps)} gap(s) in the record, "
            f"{down:.1f} s in all. Written from the store's events and positions only: no image, crop or overlay "
            "of any video is in this report." + uncertain)
