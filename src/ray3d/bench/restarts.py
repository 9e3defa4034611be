"""``ray3d bench live --mode restarts``: restarts lose nothing and count nothing twice. ``ray3d live`` on a video
read as fast as it is processed (``--unpaced``), once uninterrupted (twice: the noise between two runs), and once
killed with SIGKILL at chosen moments of the video and started again each time with the same command on the same store
until the video ends (``restarts``); then (``restarts_figures``):

- the tracks (each "track started") and the people recorded (the tracks followed for ``--min-track``) of each store;
- duplicates: events recorded twice (the same kind, place and moment, across the runs);
- events lost: what each killed run handed over (its events.jsonl) that the store lacks, and the uninterrupted run's
  events before the first kill's last second that the killed store lacks;
- the counts (entries, exits and crossings per place) of the whole store against the uninterrupted runs', and the
  same counts less what the gaps hide: the events of the people in view across a gap."""

from __future__ import annotations

import contextlib
import datetime
import json
import math
import random
import signal
import sqlite3
import subprocess
import time
from pathlib import Path

from ray3d.bench.live import fresh_folder, live_command, run_to_end, track_spans, video_seconds
from ray3d.errors import InputError
from ray3d.site.events import LINE_CROSSED, TRACK_ENDED, TRACK_STARTED, ZONE_ENTERED, ZONE_LEFT
from ray3d.store import read_record

START = "2026-12-01T09:00:00+00:00"  # every run's frame 0 (a file taken up goes on on this clock)
AFTER_RESTART_S = 2.0  # a person in view at a restart is followed again within this
LOOKED_AT_EVERY_S = 0.05  # how often a run to be killed has its store's progress read


def _restarts_command(video: Path, camera: str, site: Path | None, out: Path) -> list[str]:
    return live_command([video], [camera], out, site, "--unpaced", "--no-page", "--quiet", "--start-time", START,
                        "--every", "1h")


def kill_moments(video_s: float, kills: int, seed: int) -> list[float]:
    """Where in a video of ``video_s`` seconds the ``kills`` fall: one in each of ``kills`` equal stretches after
    the first, at a place in its middle chosen by ``seed`` (seconds of the video, increasing)."""
    chooser, stretch = random.Random(seed), video_s / (kills + 1)
    return [round(stretch * (k + 1 + chooser.uniform(-0.3, 0.3)), 1) for k in range(kills)]


def _newest_run(store: Path) -> tuple[int, float]:
    """The store's newest run and the Unix time it has committed up to ((0, -inf) before any)."""
    try:
        with contextlib.closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=1.0)) as database:
            row = database.execute("SELECT run, last_at FROM runs ORDER BY run DESC LIMIT 1").fetchone()
    except sqlite3.Error:  # not made yet, or its tables not yet
        return 0, -math.inf
    return (0, -math.inf) if row is None else (int(row[0]), -math.inf if row[1] is None else float(row[1]))


def killed_at(command: list[str], store: Path, video_s: float, limit_s: float) -> float | None:
    """Runs ``command`` until the run it begins on its store has committed the video up to ``video_s`` seconds,
    then kills it with SIGKILL: the video second it was killed at; None where the video ended first. A run that
    fails, or is still short of the moment after ``limit_s`` of wall time, is refused (``InputError``)."""
    origin = datetime.datetime.fromisoformat(START).timestamp()
    before, _ = _newest_run(store)
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + limit_s
    try:
        while process.poll() is None and time.monotonic() < deadline:
            run, committed_at = _newest_run(store)
            if run > before and committed_at - origin >= video_s:
                process.send_signal(signal.SIGKILL)
                return round(committed_at - origin, 1)
            time.sleep(LOOKED_AT_EVERY_S)
        if process.poll() is None:
            raise InputError(f"bench live restarts: ray3d live had not reached {video_s:g} s of the video after "
                             f"{limit_s:.0f} s")
        if process.returncode != 0:
            raise InputError(f"bench live restarts: ray3d live ended with exit code {process.returncode}")
        return None
    finally:
        if process.poll() is None:
            process.kill()
        process.wait()


def restarts(video: Path, camera: str, out: Path, site: Path | None = None, kills: int = 5, seed: int = 0) -> dict:
    """``ray3d live --unpaced`` on ``video`` uninterrupted (twice), and killed with SIGKILL ``kills`` times (each
    once the store holds the video up to a moment of ``kill_moments``, so that a change is measured at the same
    places) and started again each time on the same store until the video ends; then ``restarts_figures``."""
    out = fresh_folder(out)
    whole, again, killed = out / "uninterrupted", out / "uninterrupted-again", out / "killed"
    started = time.monotonic()
    run_to_end(_restarts_command(video, camera, site, whole))
    one_run_s = time.monotonic() - started
    # The same run again: how much two uninterrupted runs differ (the refinement runs on a thread of its own, so
    # when its answer lands varies with the machine's load): the noise the restarts' counts are read against.
    run_to_end(_restarts_command(video, camera, site, again))
    killed_at_s = []
    for moment in kill_moments(video_seconds(video), kills, seed):
        at = killed_at(_restarts_command(video, camera, site, killed), killed / "site.db", moment, 2 * one_run_s)
        if at is None:
            break  # it ended before its kill: the video is done
        killed_at_s.append(at)
    run_to_end(_restarts_command(video, camera, site, killed))
    return {"mode": "restarts", "killed at video s": killed_at_s, "one run s": round(one_run_s, 1),
            **restarts_figures(whole, again, killed)}


def event_counts(events: list[dict], keep=lambda event: True) -> dict:
    """Entries, exits and crossings per place among ``events``."""
    counted: dict = {}
    for event in filter(keep, events):
        if event["event"] in (ZONE_ENTERED.name, ZONE_LEFT.name):
            key = f"{event['zone']}: {event['event']}"
        elif event["event"] == LINE_CROSSED.name:
            key = f"{event['line']}: {event['direction']}"
        else:
            continue
        counted[key] = counted.get(key, 0) + 1
    return dict(sorted(counted.items()))


def _signature(event: dict) -> tuple:
    """An event as recorded: the same event twice has the same signature."""
    return (event["event"], round(event["at"], 3), json.dumps(event.get("place_m")), event.get("zone"),
            event.get("line"), event.get("direction"))


def _alike(event: dict, others: list[dict], within_s: float = 0.5) -> bool:
    """Whether ``others`` holds the same event found by another process (the refinement's thread timing may move
    it a little): the same kind at the same place within ``within_s``."""
    return any(o["event"] == event["event"] and o.get("zone") == event.get("zone") and o.get("line") ==
               event.get("line") and o.get("direction") == event.get("direction") and
               abs(o["at"] - event["at"]) <= within_s for o in others)


def _lost_at_each_kill(record, killed: Path) -> list[dict]:
    """What each killed run handed over (its events.jsonl lines, written before the store's commit) and the store
    lacks: how many, and how far before that run's last committed moment the earliest lies."""
    origin = datetime.datetime.fromisoformat(START).timestamp()
    logged = [json.loads(line) for line in (killed / "events.jsonl").read_text().splitlines()]
    kept = {_signature(e) for e in record.events}
    lost = []
    for run in record.runs[:-1]:
        mine = [{**e, "at": origin + e["time_s"]} for e in logged if e["track"].startswith(f"{run['run']}-")]
        missing = [e for e in mine if _signature(e) not in kept]
        lost.append({"handed": len(mine), "not in the store": len(missing),
                     "earliest before the last commit s": round(max(
                         [run["last_at"] - e["at"] for e in missing if run["last_at"] is not None], default=0.0), 2)})
    return lost


def _in_view_across_a_gap(reference, record, down: list[dict]) -> dict[str, set]:
    """The tracks whose events the gaps hide: in the uninterrupted run, a person seen before and after a kill's
    moment; in the killed store, a person whose track never ended before a kill, or began within
    ``AFTER_RESTART_S`` of a restart (new tracks, followed from a different history)."""
    spans = track_spans(reference.events)
    hidden_reference = {t for t, (first, last) in spans.items() for g in down
                        if first <= g["to_at"] and last >= g["from_at"] - 1.0}
    ended = {e["track"] for e in record.events if e["event"] == TRACK_ENDED.name}
    started = {e["track"]: e["at"] for e in record.events if e["event"] == TRACK_STARTED.name}
    last_run = f"{record.runs[-1]['run']}-" if record.runs else ""
    hidden_killed = {t for t in {e["track"] for e in record.events}
                     if (t not in ended and not t.startswith(last_run)) or
                     any(g["to_at"] - 0.5 <= started.get(t, -1e18) <= g["to_at"] + AFTER_RESTART_S for g in down)}
    return {"uninterrupted": hidden_reference, "killed and restarted": hidden_killed}


def restarts_figures(whole: Path, again: Path, killed: Path) -> dict:
    """The killed-and-restarted store against the uninterrupted runs' (``restarts``)."""
    reference, second, record = (read_record(folder / "site.db") for folder in (whole, again, killed))
    down = [g for g in record.gaps if g["why"] == "the service was down"]
    signatures = [_signature(e) for e in record.events]
    first_gap = down[0]["from_at"] if down else float("inf")
    hidden = _in_view_across_a_gap(reference, record, down)
    runs_of: dict[str, set] = {}  # each track's runs: those in view at a restart go on in the next
    for event in record.events:
        runs_of.setdefault(event["track"], set()).add(event["run"])
    seen = {"uninterrupted": reference.events, "uninterrupted again": second.events,
            "killed and restarted": record.events}
    return {"runs": len(record.runs),
            "gaps": [[round(g["from_at"] - record.runs[0]["first_at"], 1), round(g["to_at"] - g["from_at"], 2)]
                     for g in down],
            "events": {name: len(events) for name, events in seen.items()},
            "tracks": {name: len({e["track"] for e in events if e["event"] == TRACK_STARTED.name})
                       for name, events in seen.items()},
            # The tracks followed long enough to be people (``--min-track``): the store's people and world file.
            "people recorded": {name: len({p["person"] for p in store.people}) for name, store in
                                (("uninterrupted", reference), ("uninterrupted again", second),
                                 ("killed and restarted", record))},
            "taken up at a restart": sum(len(runs) > 1 for runs in runs_of.values()),
            "duplicated": len(signatures) - len(set(signatures)),
            "lost at each kill": _lost_at_each_kill(record, killed),
            "lost before the first kill's last second": sum(
                e["at"] <= first_gap - 1.0 and not _alike(e, record.events) for e in reference.events),
            "counts": {name: event_counts(events) for name, events in seen.items()},
            "people in view across a gap": {k: len(v) for k, v in hidden.items()},
            "counts less what the gaps hide": {
                name: event_counts(seen[name], lambda e, name=name: e["track"] not in hidden[name])
                for name in hidden},
            "ended": [r["ending"] for r in record.runs]}
