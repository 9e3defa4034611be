"""What a site's events and tracks add up to: per track (time seen, distance, speed, time in each zone, stature
class), per place (entries, exits, dwell, crossings), per person-frame (place, speed, heading, posture, zones),
zone occupancy over time, a heat map of time spent, and all of it per time bucket (``by_time``)."""

from __future__ import annotations

import datetime

import numpy as np

from ray3d.body import POSTURES, postures
from ray3d.errors import InputError
from ray3d.io.world import World
from ray3d.site.events import LINE_CROSSED, ZONE_ENTERED, ZONE_LEFT
from ray3d.site.places import Site, in_zones
from ray3d.temporal import velocity

CHILD_STATURE_M = 1.30  # a person shorter than this is a child


def track_summaries(world: World, site: Site, time_in_zones: dict[str, dict[str, float]]) -> list[dict]:
    """Per track: when it was seen (first and last time, seconds), the distance walked on the floor plan (metres,
    between consecutive frames), the mean speed, the time spent in each zone as the site's monitor counted it
    (``time_in_zones``, ``events.SiteReplay``'s: the dwell of every visit, the one under way at the track's end
    too), and the stature with its 95 % interval where the refinement ran and its class (``stature_class``)."""
    rows = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        walked = float(np.linalg.norm(np.diff(points, axis=0), axis=-1).sum())
        duration = float(times[-1] - times[0])
        refinement = result.refinement or {}
        row = {"track": track, "first_s": round(float(times[0]), 3), "last_s": round(float(times[-1]), 3),
               "distance_m": round(walked, 3), "mean_speed_m_s": round(walked / duration, 3) if duration > 0 else None,
               "stature_m": refinement.get("stature_m"),
               "stature_interval_m": refinement.get("stature_interval_m"),
               "stature_class": stature_class(refinement.get("stature_m"), refinement.get("stature_interval_m"))}
        for zone in site.zones:
            row[f"time_in_{zone.name}_s"] = round(time_in_zones[track].get(zone.name, 0.0), 3)
        rows.append(row)
    return rows


def zone_summaries(events: list[dict], site: Site, rejoined: dict | None = None) -> list[dict]:
    """Per zone: entries, exits and the visits' dwell (mean and longest, of the visits that left); per line:
    crossings each way. Each counts a person once per crossing, also where their track was taken up again after a
    gap (``rejoined``: the world's {track: its re-joins}); ``by_rejoined_tracks`` says how many of a place's
    entries or crossings such tracks made."""
    joined = set(rejoined or {})
    rows = []
    for zone in site.zones:
        mine = [e for e in events if e.get("zone") == zone.name]
        entered = [e for e in mine if e["event"] == ZONE_ENTERED.name]
        dwell = [e["dwell_s"] for e in mine if e["event"] == ZONE_LEFT.name]
        rows.append({"place": zone.name, "kind": "zone", "entries": len(entered),
                     "exits": len(dwell), "mean_dwell_s": round(float(np.mean(dwell)), 3) if dwell else None,
                     "longest_dwell_s": round(float(np.max(dwell)), 3) if dwell else None,
                     "by_rejoined_tracks": sum(e["track"] in joined for e in entered)})
    for line in site.lines:
        mine = [e for e in events if e["event"] == LINE_CROSSED.name and e["line"] == line.name]
        rows.append({"place": line.name, "kind": "line", "forward": sum(e["direction"] == "forward" for e in mine),
                     "back": sum(e["direction"] == "back" for e in mine),
                     "by_rejoined_tracks": sum(e["track"] in joined for e in mine)})
    return rows


def stature_class(stature_m: float | None, interval_m: list | None) -> str:
    """"adult", "child" (under ``CHILD_STATURE_M``), or "unsure" where the stature's interval straddles it (or
    no stature was estimated)."""
    if stature_m is None or interval_m is None:
        return "unsure"
    low, high = interval_m
    return "adult" if low >= CHILD_STATURE_M else "child" if high < CHILD_STATURE_M else "unsure"


SPEED_WINDOW_S = 0.5  # speeds and headings over this span, so that a detector's jitter does not read as motion


def person_frames(world: World, site: Site) -> list[dict]:
    """Per person-frame: the track, frame, time, floor point (x, y, metres), speed (m/s) and heading (degrees from
    +x towards +y) over ``SPEED_WINDOW_S`` around it (None where the person is slower than 0.2 m/s: no heading),
    posture (``ray3d.body.postures``) and the zones the point is in."""
    rows = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        moved, _ = velocity(times, points, SPEED_WINDOW_S / 2, SPEED_WINDOW_S / 2)
        speed = np.linalg.norm(moved, axis=-1)
        heading = np.degrees(np.arctan2(moved[:, 1], moved[:, 0]))
        classes = postures(result.joints)
        inside = in_zones(site, points)
        for k in range(len(times)):
            rows.append({"track": track, "frame": int(result.frames[k]), "time_s": round(float(times[k]), 4),
                         "x_m": round(float(points[k, 0]), 3), "y_m": round(float(points[k, 1]), 3),
                         "speed_m_s": round(float(speed[k]), 3),
                         "heading_deg": round(float(heading[k]), 1) if speed[k] >= 0.2 else None,
                         "posture": POSTURES[classes[k]],
                         "zones": [name for name, flags in inside.items() if flags[k]]})
    return rows


def heat_map(rows: list[dict], fps: float, cell_m: float = 0.5) -> tuple[np.ndarray, tuple[float, float]]:
    """Seconds spent per ``cell_m`` square of the floor plan by everybody (from ``person_frames`` rows): (H, W)
    and the (x, y) of the grid's lower-left corner."""
    xy = np.array([[row["x_m"], row["y_m"]] for row in rows]).reshape(-1, 2)
    if not len(xy):
        return np.zeros((0, 0)), (0.0, 0.0)
    low = np.floor(xy.min(axis=0) / cell_m) * cell_m
    cells = np.floor((xy - low) / cell_m).astype(int)
    grid = np.zeros((cells[:, 1].max() + 1, cells[:, 0].max() + 1))
    np.add.at(grid, (cells[:, 1], cells[:, 0]), 1.0 / fps)
    return grid, (float(low[0]), float(low[1]))


class TimeBuckets:
    """Counts per ``every_s`` seconds from the world's frame 0, taken as the events and frames come (``ray3d
    live``) or all at once (``by_time``): per zone its entries, exits, the mean dwell of the visits that left in the
    bucket and the mean and peak occupancy over its frames; per line its crossings each way. With the video's
    ``start_time`` each bucket has its wall-clock start and end too. An event counts in the bucket of its time."""

    def __init__(self, site: Site, every_s: float, start_time: datetime.datetime | None = None):
        if not every_s > 0:
            raise InputError(f"every: a time bucket must be longer than 0 s, got {every_s}", ("every",))
        self.site, self.every_s, self.start_time = site, float(every_s), start_time
        self._counts: dict[int, dict] = {}

    def _bucket(self, time_s: float) -> dict:
        k = max(0, int(time_s // self.every_s))
        if k not in self._counts:
            self._counts[k] = {"entries": {}, "dwell": {}, "people": {}, "peak": {}, "frames": 0,
                               "forward": {}, "back": {}}
        return self._counts[k]

    def add(self, events: list[dict]) -> None:
        for event in events:
            kind = event["event"]
            if kind == ZONE_ENTERED.name:
                counts = self._bucket(event["time_s"])["entries"]
                counts[event["zone"]] = counts.get(event["zone"], 0) + 1
            elif kind == ZONE_LEFT.name:
                self._bucket(event["time_s"])["dwell"].setdefault(event["zone"], []).append(event["dwell_s"])
            elif kind == LINE_CROSSED.name:
                counts = self._bucket(event["time_s"])[event["direction"]]
                counts[event["line"]] = counts.get(event["line"], 0) + 1

    def observe(self, time_s: float, occupancy: dict[str, int]) -> None:
        """A frame at ``time_s`` with {zone: people in it}."""
        bucket = self._bucket(time_s)
        bucket["frames"] += 1
        for zone, people in occupancy.items():
            bucket["people"][zone] = bucket["people"].get(zone, 0) + int(people)
            bucket["peak"][zone] = max(bucket["peak"].get(zone, 0), int(people))

    def rows(self, until_s: float = 0.0) -> list[dict]:
        """Every bucket from 0 to the last with anything in it (or holding ``until_s``), in order."""
        last = max([*self._counts, int(max(until_s, 0.0) // self.every_s)])
        rows = []
        for k in range(last + 1):
            bucket = self._counts.get(k) or {"entries": {}, "dwell": {}, "people": {}, "peak": {}, "frames": 0,
                                             "forward": {}, "back": {}}
            start, end = k * self.every_s, (k + 1) * self.every_s
            row: dict = {"start_s": round(start, 3), "end_s": round(end, 3)}
            if self.start_time is not None:
                row["start"] = (self.start_time + datetime.timedelta(seconds=start)).isoformat()
                row["end"] = (self.start_time + datetime.timedelta(seconds=end)).isoformat()
            for zone in self.site.zones:
                left = bucket["dwell"].get(zone.name, [])
                frames = bucket["frames"]
                row.update({f"{zone.name}: entries": bucket["entries"].get(zone.name, 0),
                            f"{zone.name}: exits": len(left),
                            f"{zone.name}: mean dwell s": round(float(np.mean(left)), 3) if left else None,
                            f"{zone.name}: mean occupancy":
                                round(bucket["people"].get(zone.name, 0) / frames, 3) if frames else 0.0,
                            f"{zone.name}: peak occupancy": bucket["peak"].get(zone.name, 0)})
            for line in self.site.lines:
                row.update({f"{line.name}: forward": bucket["forward"].get(line.name, 0),
                            f"{line.name}: back": bucket["back"].get(line.name, 0)})
            rows.append(row)
        return rows


def by_time(events: list[dict], occupancy_times: np.ndarray, occupancy_counts: dict[str, np.ndarray], site: Site,
            every_s: float, end_s: float, start_time: datetime.datetime | None = None) -> list[dict]:
    """A finished world's ``TimeBuckets``: its events, and its occupancy frame by frame (``occupancy``), in
    buckets from frame 0 to ``end_s``; every count adds up to the whole run's."""
    buckets = TimeBuckets(site, every_s, start_time)
    buckets.add(events)
    for k, time_s in enumerate(occupancy_times):
        buckets.observe(float(time_s), {name: counts[k] for name, counts in occupancy_counts.items()})
    return buckets.rows(end_s)
