"""What a run beginning on a store takes over from the runs before it (``RunRecorder`` calls these as the store's one
writer, so no other run is under way):

- ``take_over_cut_off_runs``: a run cut off (killed outright, the machine stopped: its end never noted) left the
  people in view open: each "track started" without its "track ended", each "zone entered" of theirs without its
  "zone left". Where the new run takes up the same one file where the cut-off run stopped (its stream clock goes
  on), they are *carried* (``site.events.CarriedPerson``: their last place, where their tracker last placed them,
  how they walked and what they wore (``in_view``), their visits under way): the new run's tracker gives a person
  it finds there in its first seconds the carried one's id, and its site monitor goes on from their visits; the
  store keeps them in ``carried`` until their track ends, so a run cut off again carries them again. Otherwise (a
  live stream, several inputs) each gets its ending events, dated at the cut-off run's last commit, with ``reason``
  "the service stopped" (``CarriedPerson.closing``). The cut-off runs are then noted as ended ("cut off"): every
  track in the store ends.
- ``counts_so_far``: each zone's entries and exits and each line's crossings over every run, as a
  ``SiteMonitor`` counts them: MQTT's running counts go on from them."""

from __future__ import annotations

import json

from ray3d.site.events import LINE_CROSSED, TRACK_ENDED, TRACK_STARTED, ZONE_ENTERED, ZONE_LEFT, CarriedPerson
from ray3d.store.database import Database

CUT_OFF = "cut off"  # the ending of a run whose end was never noted, once the next run has closed it
LAST_PLACE_S = 10.0  # a person's last place: their latest position in this many seconds before the last commit
OPENING_AND_CLOSING = (TRACK_STARTED.name, TRACK_ENDED.name, ZONE_ENTERED.name, ZONE_LEFT.name)
FOLLOWED = (*OPENING_AND_CLOSING, LINE_CROSSED.name)  # what a carried person's state is rebuilt from


def take_over_cut_off_runs(database: Database, carry: bool = False) -> tuple[list[dict], list[CarriedPerson]]:
    """What the cut-off runs left open (not committed): with ``carry`` (the new run takes up the one file they
    followed, on its clock) the people carried and kept in ``carried``; without, every one closed: the closing
    events, in order (each visit's "zone left", then its track's "track ended"), written under the newest cut-off
    run. Returns (closing events, carried people)."""
    cut_off = [(int(run), float(last_at)) for run, last_at in database.rows(
        "SELECT run, last_at FROM runs WHERE ending IS NULL AND last_at IS NOT NULL ORDER BY run")]
    started = {person: int(run) for person, run in database.rows("SELECT person, run FROM carried")}
    for run, _ in cut_off:
        started.update({person: run for (person,) in database.rows(
            "SELECT person FROM events WHERE run = ? AND kind = ?", (run, TRACK_STARTED.name))})
    last_at = max((at for _, at in cut_off), default=None)
    open_people = _open(database, started, last_at) if last_at is not None else []
    closing, carried = [], []
    if not carry:
        newest = max(run for run, _ in cut_off) if cut_off else None
        closing = [event for person in open_people for event in person.closing()]
        if closing:
            seq = int(database.rows("SELECT COALESCE(MAX(seq), -1) FROM events WHERE run = ?", (newest,))[0][0])
            database.many("INSERT INTO events (run, seq, at, time_s, kind, person, body) VALUES (?, ?, ?, ?, ?, ?, ?)",
                          [(newest, seq + k + 1, last_at, event["time_s"], event["event"], event["track"],
                            json.dumps(event)) for k, event in enumerate(closing)])
        database.execute("DELETE FROM carried")
        database.execute("DELETE FROM in_view")  # every track is closed
    else:
        carried = open_people
        database.execute("DELETE FROM carried")
        database.many("INSERT INTO carried (person, run) VALUES (?, ?)",
                      [(person.person, started[person.person]) for person in open_people])
        # Who else was placed (followed for a moment, never announced) is not taken up.
        database.execute("DELETE FROM in_view WHERE person NOT IN (SELECT person FROM carried)")
    database.execute("UPDATE runs SET ending = ? WHERE ending IS NULL", (CUT_OFF,))
    return closing, carried


def _open(database: Database, started: dict[str, int], last_at: float) -> list[CarriedPerson]:
    """Of the people ``started`` (person -> the run their track began in), those whose track never ended, on the
    clock of their own track (times in seconds since its frame 0: a file taken up keeps the clock it was begun on),
    their run's end at ``last_at`` (Unix time)."""
    if not started:
        return []
    # open track -> its frame 0 (Unix time); its latest (x, y, at); its visits; when it last crossed each line
    clock, place, visits, crossed = {}, {}, {}, {}
    for run, at, time_s, kind, person, body in database.rows(
            "SELECT run, at, time_s, kind, person, body FROM events WHERE run >= ? AND kind IN (?, ?, ?, ?, ?) "
            "ORDER BY run, seq", (min(started.values()), *FOLLOWED)):
        if person not in started:
            continue
        event = json.loads(body)
        if kind == TRACK_STARTED.name:
            clock[person] = float(at) - float(time_s)
        elif kind == TRACK_ENDED.name:
            clock.pop(person, None)
        elif kind == ZONE_ENTERED.name:
            visits.setdefault(person, {})[event["zone"]] = float(at)
        elif kind == ZONE_LEFT.name:
            visits.get(person, {}).pop(event["zone"], None)
        else:
            crossed.setdefault(person, {})[event["line"]] = float(at)
            continue  # a crossing's place is on the line, no side of it
        if event.get("place_m") is not None:
            place[person] = (*event["place_m"], float(at))
    for person, x, y, at in database.rows("SELECT person, x, y, at FROM positions WHERE at >= ? ORDER BY at",
                                          (last_at - LAST_PLACE_S,)):
        if person in clock:
            place[person] = (round(float(x), 3), round(float(y), 3), float(at))
    tracked, walk, clothes = {}, {}, {}
    for person, x, y, at, vx, vy, colours in database.rows("SELECT person, x, y, at, vx, vy, clothes FROM in_view"):
        if person in clock:
            tracked[person] = (round(float(x), 3), round(float(y), 3), float(at) - clock[person])
            walk[person] = None if vx is None or vy is None else (float(vx), float(vy))
            clothes[person] = None if colours is None else tuple(json.loads(colours))
    people = []
    for person, origin in clock.items():
        x, y, at = place.get(person, (None, None, last_at))
        people.append(CarriedPerson(person, None if x is None else (x, y), at - origin, last_at - origin,
                                    {zone: entered - origin for zone, entered in visits.get(person, {}).items()},
                                    {line: when - origin for line, when in crossed.get(person, {}).items()},
                                    tracked.get(person), walk.get(person), clothes.get(person)))
    return people


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
