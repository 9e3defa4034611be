"""``ray3d bench live``: the real ``ray3d live`` command line run as its own process, as a service runs it (and as
only a process can be killed), and measured from outside:

- ``soak``: a video looped at its own rate for a long time, the page read by a client as a browser would; the
  process's memory every few seconds; every event written and in the store; the frames dropped and the latency;
- ``restarts`` (``bench.restarts``): killed with SIGKILL at moments of the video chosen by a seed and started again
  on the same store;
- ``rtsp``: the video served over RTSP on 127.0.0.1 (rtsp-server-perl fed by FFmpeg) and stopped for a few seconds
  several times: the run goes on, each outage a gap in the store, nobody counted across a gap;
- ``cluster``: one and two cameras on a local Ray (``--address local``), the frames each keeps; and the same video
  followed in one process and on Ray, their worlds matched track by track (``bench.worlds``).

Each returns a dict of figures (``ray3d bench live`` writes it to OUT/<mode>.json)."""

from __future__ import annotations

import math
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

from ray3d.bench.worlds import compare_worlds
from ray3d.errors import InputError
from ray3d.site.events import TRACK_STARTED
from ray3d.store import read_record
from ray3d.video import read_video_info

# The command line's closing line (cli/live_commands.py): what the process itself counted.
CLOSING = re.compile(r"(?P<processed>\d+) of (?P<read>\d+) frames processed \((?P<dropped>\d+) dropped.*?latency "
                     r"median (?P<median>\S+) ms, 99th percentile (?P<p99>\S+) ms; (?P<events>\d+) events; "
                     r"(?P<people>\d+) people in (?P<world>\S+) \(")
LOST_ROWS = re.compile(r"; (\d+) rows lost")


def live_command(sources: list[str], cameras: list[str], out: Path, site: Path | None, *flags: str) -> list[str]:
    """``ray3d live`` on ``sources`` (one camera file each) into ``out``, with ``flags``, as this Python runs it."""
    command = [sys.executable, "-m", "ray3d.cli", "live", *map(str, sources)]
    for camera in cameras:
        command += ["--camera", str(camera)]
    if site is not None:
        command += ["--site", str(site)]
    return [*command, "--out", str(out), *flags]


def closing_figures(stderr: str) -> dict:
    """What a ``ray3d live`` run said of itself as it ended (frames read, processed and dropped, latency, events,
    people and its world file, store rows lost); {} where it said nothing (it was killed)."""
    found = CLOSING.search(stderr)
    if found is None:
        return {}
    read, dropped = int(found["read"]), int(found["dropped"])
    lost = LOST_ROWS.search(stderr)
    return {"read": read, "processed": int(found["processed"]), "dropped": dropped,
            "dropped_percent": round(100 * dropped / max(read, 1), 2), "latency_median_ms": float(found["median"]),
            "latency_p99_ms": float(found["p99"]), "events": int(found["events"]), "people": int(found["people"]),
            "world": found["world"], "store_rows_lost": int(lost[1]) if lost else 0}


def run_to_end(command: list[str], env: dict | None = None) -> dict:
    """A run of ``command`` to its end: its exit code and closing figures (refused: its one line of stderr)."""
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=None if env is None else {**os.environ, **env})
    if done.returncode == 2:
        raise InputError(f"bench live: ray3d live refused it: {done.stderr.strip().splitlines()[-1]}")
    return {"exit_code": done.returncode, **closing_figures(done.stderr)}


def track_spans(events: list[dict]) -> dict[str, tuple[float, float]]:
    """Each track's first and last moment (Unix seconds) among a store's ``events``."""
    spans: dict = {}
    for event in events:
        first, last = spans.get(event["track"], (event["at"], event["at"]))
        spans[event["track"]] = (min(first, event["at"]), max(last, event["at"]))
    return spans


def fresh_folder(out: Path) -> Path:
    """``out``, made; refused where it holds anything (a store appended to would mix two benchmarks)."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"bench live: {out} is not an empty folder; give a new one", arguments=("out",))
    out.mkdir(parents=True, exist_ok=True)
    return out


def video_seconds(video: str | Path) -> float:
    info = read_video_info(video)
    return info.frames / info.fps


def looped(video: Path, seconds: float, out: Path) -> Path:
    """``video`` played again and again for at least ``seconds`` of its time: itself where it is long enough, else
    copies of it one after another (FFmpeg, the stream copied, not re-encoded) in ``out``."""
    loops = math.ceil(seconds / video_seconds(video)) - 1
    if loops <= 0:
        return video
    if shutil.which("ffmpeg") is None:
        raise InputError(f"bench live soak: {seconds:g} s is longer than {video}; looping it needs ffmpeg")
    subprocess.run(["ffmpeg", "-loglevel", "error", "-stream_loop", str(loops), "-i", str(video), "-c", "copy",
                    str(out)], check=True)
    return out


def _resident_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return None


def _read_page(url: str, stop: threading.Event, counter: list) -> None:
    """The page's feed read as a browser reads it: ``counter[0]`` the snapshots received."""
    try:
        with urllib.request.urlopen(url + "stream", timeout=60) as feed:
            for line in feed:
                if stop.is_set():
                    return
                counter[0] += line.startswith(b"data: ")
    except OSError:  # the run ended and took its page with it
        return


def soak(video: Path, camera: str, out: Path, site: Path | None = None, minutes: float = 30.0,
         sample_s: float = 10.0) -> dict:
    """``ray3d live`` on ``video`` looped at its own rate for ``minutes``, its page read by a client, its memory
    noted every ``sample_s`` (thirty times at least): frames dropped, latency, events said / written / stored, store
    rows lost, the memory after the first minute and its largest rise after that."""
    out = fresh_folder(out)
    seconds = math.ceil(60 * minutes)
    sample_s = min(sample_s, seconds / 30)
    source = looped(video, seconds, out / f"looped{video.suffix}")
    command = live_command([source], [camera], out / "live", site, "--port", "0", "--quiet", "--until", f"{seconds}s")
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    said, stop, snapshots = [], threading.Event(), [0]

    def listen() -> None:  # stderr: the page's address (then read it) and, at the end, the closing line
        for line in process.stderr:
            said.append(line)
            if line.startswith("live page: "):
                threading.Thread(target=_read_page, args=(line.split(": ", 1)[1].strip(), stop, snapshots),
                                 daemon=True).start()

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    started, samples = time.monotonic(), []
    while process.poll() is None:
        rss = _resident_mb(process.pid)
        if rss is not None:
            samples.append((time.monotonic() - started, rss))
        try:
            process.wait(timeout=sample_s)
        except subprocess.TimeoutExpired:
            pass
    stop.set()
    listener.join()
    figures = closing_figures("".join(said))
    if process.returncode == 2 or not figures:
        raise InputError(f"bench live soak: ray3d live ended with {process.returncode}: {''.join(said[-1:]).strip()}")
    events = out / "live" / "events.jsonl"
    return {"mode": "soak", "command": " ".join(command), "exit_code": process.returncode,
            "minutes": round((time.monotonic() - started) / 60, 2), **figures,
            "events_written": len(events.read_text().splitlines()) if events.exists() else 0,
            "events_in_the_store": len(read_record(out / "live" / "site.db").events),
            "snapshots_read_by_the_page_client": snapshots[0], **memory_figures(samples)}


def memory_figures(samples: list[tuple[float, float]]) -> dict:
    """A run's resident memory ((seconds from its start, MB) samples): all of them, its peak, and after its first
    minute (models loaded, queues filled) where it lasted that long: the first, the largest rise over it, the last."""
    after_minute = [rss for at, rss in samples if at >= 60]
    figures = {"rss_mb_samples": [[round(at, 1), round(rss, 1)] for at, rss in samples],
               "rss_mb_peak": round(max((rss for _, rss in samples), default=0.0), 1)}
    if after_minute:
        figures.update(rss_mb_at_1_min=round(after_minute[0], 1), rss_mb_last=round(after_minute[-1], 1),
                       rss_mb_largest_rise_after_1_min=round(max(after_minute) - after_minute[0], 1))
    return figures


def rtsp(video: Path, camera: str, out: Path, site: Path | None = None, seconds: float = 75.0, outages: int = 3,
         down_s: float = 4.0) -> dict:
    """``ray3d live`` following ``video`` served over RTSP on 127.0.0.1 (rtsp-server-perl, FFmpeg publishing it in
    a loop at its rate) for ``seconds``, the publisher stopped ``outages`` times for ``down_s``, evenly apart: its
    exit code, the gaps its store recorded and the people with events on both sides of a gap."""
    up_s = (seconds - outages * down_s) / (outages + 1)
    if up_s <= 0:
        raise InputError(f"bench live rtsp: --seconds {seconds:g} leaves no time between {outages} outages of "
                         f"{down_s:g} s")
    missing = [tool for tool in ("rtsp-server-perl", "ffmpeg") if shutil.which(tool) is None]
    if missing:
        raise InputError(f"bench live rtsp needs {' and '.join(missing)} (Debian packages)")
    out = fresh_folder(out)
    client, publishing = _free_port(), _free_port()
    logs = open(out / "server.log", "w"), open(out / "publisher.log", "w")
    server = subprocess.Popen(["rtsp-server-perl", "--clientport", str(client), "--serverport", str(publishing),
                               "--client_listen_address", "127.0.0.1", "--source_listen_address", "127.0.0.1",
                               "--rtp_start_port", str(20000 + _free_port() % 20000)], stdout=logs[0], stderr=logs[0])
    _wait_for_port(publishing)

    def publish() -> subprocess.Popen:
        return subprocess.Popen(["ffmpeg", "-loglevel", "error", "-re", "-stream_loop", "-1", "-i", str(video),
                                 "-c:v", "mpeg4", "-q:v", "4", "-g", "10", "-f", "rtsp",
                                 f"rtsp://127.0.0.1:{publishing}/vtest"], stdout=logs[1], stderr=logs[1])

    publisher = publish()
    try:
        time.sleep(3.0)  # the stream published before anybody reads it
        command = live_command([f"rtsp://127.0.0.1:{client}/vtest"], [camera], out / "live", site, "--no-page",
                               "--quiet", "--until", f"{math.ceil(seconds)}s", "--stall-timeout", "2",
                               "--reconnect-max", str(down_s))
        # This server has no TCP transport: OpenCV's FFmpeg reads it over UDP.
        follower = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                    env={**os.environ, "OPENCV_FFMPEG_CAPTURE_OPTIONS": "rtsp_transport;udp"})
        said: list[str] = []
        listener = threading.Thread(target=lambda: said.extend(follower.stderr), daemon=True)
        listener.start()
        for _ in range(outages):
            time.sleep(up_s)
            publisher.terminate()
            publisher.wait()
            time.sleep(down_s)
            publisher = publish()
        follower.wait()
        listener.join()
    finally:
        for process in (publisher, server):
            process.terminate()
            process.wait()
        for log in logs:
            log.close()
    (out / "live.log").write_text("".join(said))
    if not (out / "live" / "site.db").exists():
        raise InputError(f"bench live rtsp: ray3d live ended with {follower.returncode} before its store: "
                         f"{''.join(said[-1:]).strip()} (all it said: {out / 'live.log'})")
    record = read_record(out / "live" / "site.db")
    spans = track_spans(record.events)
    return {"mode": "rtsp", "command": " ".join(command), "exit_code": follower.returncode,
            **closing_figures("".join(said)),
            "gaps": [{"s": round(g["to_at"] - g["from_at"], 1), "why": g["why"]} for g in record.gaps],
            "tracks started": sum(e["event"] == TRACK_STARTED.name for e in record.events),
            "people with events on both sides of a gap": sum(
                first < g["from_at"] and last > g["to_at"] for first, last in spans.values() for g in record.gaps)}


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _wait_for_port(port: int, timeout_s: float = 30.0) -> None:
    """Until a server listens on ``port`` of 127.0.0.1 (a busy machine starts one slowly)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise InputError(f"bench live rtsp: the RTSP server did not listen on port {port} within "
                                 f"{timeout_s:g} s") from None
            time.sleep(0.2)


def cluster(video: Path, camera: str, out: Path, seconds: float = 40.0, cameras: tuple[int, ...] = (1, 2)) -> dict:
    """``ray3d live --address local``: ``video`` played at its rate to each of ``cameras`` camera actors (one CPU
    each) for ``seconds``, the frames dropped; and the video read whole (``--unpaced``) in one process and on Ray,
    the two worlds matched track by track (median pelvis floor distance)."""
    out = fresh_folder(out)
    rows = []
    for count in cameras:
        figures = run_to_end(live_command([video] * count, [camera] * count, out / f"ray-{count}", None,
                                          "--address", "local", "--workers", str(count), "--until",
                                          f"{math.ceil(seconds)}s", "--no-page", "--quiet"))
        rows.append({"cameras": count, **figures})
    worlds = [run_to_end(live_command([video], [camera], out / name, None, "--unpaced", "--no-page", "--quiet",
                                      *flags))["world"]
              for name, flags in (("one-process", ()), ("on-ray", ("--address", "local", "--workers", "1")))]
    return {"mode": "cluster", "paced": rows, "one process against Ray": compare_worlds(*worlds)}
