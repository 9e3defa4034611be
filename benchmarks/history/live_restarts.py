"""Restarts lose nothing and count nothing twice: ``ray3d live`` on a video read as fast as it is processed
(``--unpaced``), once uninterrupted, and once killed with SIGKILL at ``--kills`` random moments and started again
each time with the same command on the same output (its store: OUT/site.db), until the video ends. Then:

- duplicates: events recorded twice (the same kind, place and moment, across the runs);
- events lost: the uninterrupted run's events up to each kill's last committed second that the killed store lacks
  (for the first kill the two runs are the same computation; after a restart, people in view at the kill are
  new tracks, so only what happened before the kill is compared);
- the counts (entries, exits and crossings per place) of the whole store against the uninterrupted run's, and
  the same counts less what the gaps hide: the events of the people in view across a gap (in the uninterrupted
  run, a person seen before and after a kill's moment; in the killed store, a person whose track never ended
  before a kill, or began within 2 s of a restart: they are new tracks, followed from a different history).

    python benchmarks/live_restarts.py ../shared/data/real-video/vtest.avi \\
        --camera ../shared/data/real-video/vtest_camera.json --site benchmarks/vtest_site.json --out DIR
"""

from __future__ import annotations

import argparse
import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from ray3d.store import read_record

AFTER_RESTART_S = 2.0  # a person in view at a restart is followed again within this


def _command(video: str, camera: str, site: str, out: Path) -> list[str]:
    return [sys.executable, "-m", "ray3d.cli", "live", video, "--camera", camera, "--site", site, "--unpaced",
            "--no-page", "--quiet", "--out", str(out), "--start-time", START, "--every", "1h"]


def _counts(events: list[dict], keep=lambda at: True) -> dict:
    counted: dict = {}
    for event in events:
        if not keep(event["at"]):
            continue
        if event["event"] in ("zone entered", "zone left"):
            key = f"{event['zone']}: {event['event']}"
        elif event["event"] == "line crossed":
            key = f"{event['line']}: {event['direction']}"
        else:
            continue
        counted[key] = counted.get(key, 0) + 1
    return dict(sorted(counted.items()))


START = "2026-12-01T09:00:00+00:00"  # every run's frame 0 (a file taken up goes on on this clock)


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("video")
    parser.add_argument("--camera", required=True)
    parser.add_argument("--site", required=True)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--kills", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--analyse", action="store_true", help="only analyse the outputs of an earlier run in --out")
    args = parser.parse_args()
    whole, killed = args.out / "uninterrupted", args.out / "killed"
    if not args.analyse:
        run(args, whole, killed)
    analyse(whole, killed)


def run(args, whole: Path, killed: Path) -> None:
    start = time.monotonic()
    subprocess.run(_command(args.video, args.camera, args.site, whole), check=True, stderr=subprocess.DEVNULL)
    one_run_s = time.monotonic() - start
    # The same run again: how much two uninterrupted runs differ (the refinement runs on a thread of its own, so
    # when its answer lands varies with the machine's load): the noise the restarts' counts are read against.
    subprocess.run(_command(args.video, args.camera, args.site, whole.parent / "uninterrupted-again"), check=True,
                   stderr=subprocess.DEVNULL)
    chooser = random.Random(args.seed)
    kills = []
    for k in range(args.kills):
        process = subprocess.Popen(_command(args.video, args.camera, args.site, killed), stderr=subprocess.DEVNULL)
        wait = chooser.uniform(8.0, one_run_s / (args.kills + 1))  # models load first: a kill after some frames
        time.sleep(wait)
        if process.poll() is not None:
            break
        process.send_signal(signal.SIGKILL)
        process.wait()
        kills.append(round(wait, 1))
    subprocess.run(_command(args.video, args.camera, args.site, killed), check=True, stderr=subprocess.DEVNULL)
    (args.out / "kills.json").write_text(json.dumps({"kills after s": kills, "one run s": round(one_run_s, 1)}))


def analyse(whole: Path, killed: Path) -> None:
    import datetime

    reference, record = read_record(whole / "site.db"), read_record(killed / "site.db")
    again = read_record(whole.parent / "uninterrupted-again" / "site.db")
    down = [g for g in record.gaps if g["why"] == "the service was down"]
    signatures = [_signature(e) for e in record.events]
    duplicated = len(signatures) - len(set(signatures))
    kept = set(signatures)
    first_gap = down[0]["from_at"] if down else float("inf")
    lost_before_first = [e for e in reference.events if e["at"] <= first_gap - 1.0 and not _alike(e, record.events)]
    # What each killed run handed over (its events.jsonl lines, written before the store's commit) and the store
    # lacks: how far before that run's last committed moment each lies.
    origin = datetime.datetime.fromisoformat(START).timestamp()
    logged = [json.loads(line) for line in (killed / "events.jsonl").read_text().splitlines()]
    lost_per_kill = []
    for run in record.runs[:-1]:
        mine = [{**e, "at": origin + e["time_s"]} for e in logged if e["track"].startswith(f"{run['run']}-")]
        missing = [e for e in mine if _signature(e) not in kept]
        lost_per_kill.append({"handed": len(mine), "not in the store": len(missing),
                              "earliest before the last commit s": round(max(
                                  [run["last_at"] - e["at"] for e in missing], default=0.0), 2)})
    spans = {}
    for event in reference.events:
        first, last = spans.get(event["track"], (event["at"], event["at"]))
        spans[event["track"]] = (min(first, event["at"]), max(last, event["at"]))
    hidden_reference = {t for t, (first, last) in spans.items() for g in down if first <= g["to_at"] and
                        last >= g["from_at"] - 1.0}
    ended = {e["track"] for e in record.events if e["event"] == "track ended"}
    started = {e["track"]: e["at"] for e in record.events if e["event"] == "track started"}
    hidden_killed = {t for t in {e["track"] for e in record.events} if
                     (t not in ended and not t.startswith(f"{record.runs[-1]['run']}-")) or
                     any(g["to_at"] - 0.5 <= started.get(t, -1e18) <= g["to_at"] + AFTER_RESTART_S for g in down)}
    hidden = {"uninterrupted": hidden_reference, "killed and restarted": hidden_killed}
    runs_of: dict[str, set] = {}  # each track's runs: those in view at a restart go on in the next
    for event in record.events:
        runs_of.setdefault(event["track"], set()).add(event["run"])
    seen = {"uninterrupted": reference.events, "uninterrupted again": again.events,
            "killed and restarted": record.events}
    result = {"runs": len(record.runs), **json.loads((killed.parent / "kills.json").read_text()),
              "gaps": [[round(g["from_at"] - record.runs[0]["first_at"], 1), round(g["to_at"] - g["from_at"], 2)]
                       for g in down],
              "events": {"uninterrupted": len(reference.events), "killed and restarted": len(record.events)},
              "tracks": {name: len({e["track"] for e in events if e["event"] == "track started"})
                         for name, events in (("uninterrupted", reference.events),
                                              ("killed and restarted", record.events))},
              "taken up at a restart": sum(len(runs) > 1 for runs in runs_of.values()),
              "duplicated": duplicated, "lost at each kill": lost_per_kill,
              "lost before the first kill's last second": len(lost_before_first),
              "counts": {"uninterrupted": _counts(reference.events), "uninterrupted again": _counts(again.events),
                         "killed and restarted": _counts(record.events)},
              "people in view across a gap": {k: len(v) for k, v in hidden.items()},
              "counts less what the gaps hide": {
                  name: _counts([e for e in seen[name] if e["track"] not in hidden[name]])
                  for name in ("uninterrupted", "killed and restarted")},
              "ended": [r["ending"] for r in record.runs]}
    for key, value in result.items():
        print(f"{key}: {json.dumps(value)}")


if __name__ == "__main__":
    main()
