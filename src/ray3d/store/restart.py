"""What a run beginning on a store takes over from the runs before it (``RunRecorder`` calls these as the store's one
writer, so no other run is under way):

- ``close_cut_off_runs``: a run cut off (killed outright, the machine stopped: its end never noted) left the people
  in view open: each "track started" without its "track ended", each "zone entered" of theirs without its "zone
  left". Each gets its ending event, dated at that run's last commit, with ``reason`` "the service stopped", written
  under that run, which is then noted as ended ("cut off"): every track in the store ends.
- ``counts_so_far``: each zone's entries and exits and each line's crossings over every run, as a
  ``SiteMonitor`` counts them: MQTT's running counts go on from them."""

from __future__ import annotations

import json

from ray3d.site.events import LINE_CROSSED, TRACK_ENDED, TRACK_STARTED, ZONE_ENTERED, ZONE_LEFT, Event
from ray3d.store.database import Database

SERVICE_STOPPED = "the service stopped"  # the reason of the events that close what a cut-off run left open
CUT_OFF = "cut off"  # the ending of a run whose end was never noted, once the next run has closed it
LAST_PLACE_S = 10.0  # a person's last place: their latest position in this many seconds before the last commit
OPENING_AND_CLOSING = (TRACK_STARTED.name, TRACK_ENDED.name, ZONE_ENTERED.name, ZONE_LEFT.name)


def close_cut_off_runs(database: Database) -> list[dict]:
    """Every track and zone visit the cut-off runs left open closed in ``database`` (not committed): the closing
    events, in order (each visit's "zone left", then its track's "track ended")."""
    closing = []
    for run, last_at in database.rows("SELECT run, last_at FROM runs WHERE ending IS NULL ORDER BY run"):
        if last_at is not None:
            closing += _close_run(database, int(run), float(last_at))
        database.execute("UPDATE runs SET ending = ? WHERE run = ?", (CUT_OFF, run))
    return closing


def _close_run(database: Database, run: int, last_at: float) -> list[dict]:
    clock, place, visits = {}, {}, {}  # open track -> its run's frame 0 (Unix time); its latest place; its visits
    for at, time_s, kind, person, body in database.rows(
            "SELECT at, time_s, kind, person, body FROM events WHERE run = ? AND kind IN (?, ?, ?, ?) ORDER BY seq",
            (run, *OPENING_AND_CLOSING)):
        event = json.loads(body)
        if kind == TRACK_STARTED.name:
            clock[person] = float(at) - float(time_s)
        elif kind == TRACK_ENDED.name:
            clock.pop(person, None)
        elif kind == ZONE_ENTERED.name:
            visits.setdefault(person, {})[event["zone"]] = float(at)
        else:
            visits.get(person, {}).pop(event["zone"], None)
        if event.get("place_m") is not None:
            place[person] = event["place_m"]
    if not clock:
        return []
    for person, x, y in database.rows("SELECT person, x, y FROM positions WHERE run = ? AND at >= ? ORDER BY at",
                                      (run, last_at - LAST_PLACE_S)):
        place[person] = [round(float(x), 3), round(float(y), 3)]
    seq = int(database.rows("SELECT COALESCE(MAX(seq), -1) FROM events WHERE run = ?", (run,))[0][0])
    closing = []
    for person, origin in clock.items():
        time_s, where = round(last_at - origin, 3), place.get(person)
        # No frame saw these ends: ``frames`` is empty.
        closing += [Event(ZONE_LEFT, person, time_s, zone=zone, place_m=where, dwell_s=round(last_at - entered, 3),
                          frames=[], reason=SERVICE_STOPPED) for zone, entered in visits.get(person, {}).items()]
        closing.append(Event(TRACK_ENDED, person, time_s, place_m=where, frames=[], reason=SERVICE_STOPPED))
    rows = [(run, seq + k + 1, last_at, event["time_s"], event["event"], event["track"], json.dumps(event))
            for k, event in enumerate(closing)]
    database.many("INSERT INTO events (run, seq, at, time_s, kind, person, body) VALUES (?, ?, ?, ?, ?, ?, ?)", rows)
    return closing


def counts_so_far(database: Database) -> dict[str, dict[str, int]]:
    """{zone: {"entered": n, "left": n}, line: {"forward": n, "back": n}} over every event of the store, the form of
    ``SiteMonitor.counts``."""
    counts: dict[str, dict[str, int]] = {}
    for kind, body in database.rows("SELECT kind, body FROM events WHERE kind IN (?, ?, ?)",
                                    (ZONE_ENTERED.name, ZONE_LEFT.name, LINE_CROSSED.name)):
        event = json.loads(body)
        if kind == LINE_CROSSED.name:
            counts.setdefault(event["line"], {"forward": 0, "back": 0})[event["direction"]] += 1
        else:
            counts.setdefault(event["zone"], {"entered": 0, "left": 0})[
                "entered" if kind == ZONE_ENTERED.name else "left"] += 1
    return counts
