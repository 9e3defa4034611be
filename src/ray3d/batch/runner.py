"""Batch jobs on Ray: every input of a manifest is one Ray task (detection and tracking for a video, lifting,
refinement, the world file and a summary), on a local Ray started for the job or on an existing cluster.

Each input's outputs go to ``OUT/NAME/``: made in a temporary folder beside it and renamed into place when
complete, so a killed job leaves either a whole output or none, and a job run again skips every input whose
output exists with the same fingerprint (options, input and camera files, model weights). A bad input (an
``InputError``: its file is unreadable, its keypoints do not fit its camera, ...) fails at once; any other
failure (a crashed worker, a lost node, an exception) is retried up to ``retries`` times. ``OUT/summary.csv``
lists every input with its status, frames, people, seconds and error.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from ray3d.batch.manifest import Entry, read_manifest
from ray3d.console import progress_bar
from ray3d.errors import InputError
from ray3d.io.atomic import atomic_path
from ray3d.jobs.cluster import start_ray

SUMMARY_FILE = "summary.csv"
DONE_FILE = "done.json"  # written last into an input's output folder: its fingerprint and summary
SUMMARY_FIELDS = ("name", "input", "status", "frames", "people", "seconds", "error")


@dataclasses.dataclass
class InputReport:
    """How one input went: ``status`` is done, skipped (its output was up to date) or failed."""

    name: str
    input: str
    status: str
    frames: int | None = None
    people: int | None = None
    seconds: float | None = None
    error: str = ""


@dataclasses.dataclass
class BatchReport:
    reports: list[InputReport]
    summary: Path

    @property
    def failed(self) -> list[InputReport]:
        return [r for r in self.reports if r.status == "failed"]


def process_entry(entry: Entry, out_dir: Path, fingerprint: str, threads: int = 1) -> dict:
    """Make one input's outputs in ``out_dir / entry.name`` (what ``ray3d lift`` or ``ray3d video`` writes for
    it, plus ``done.json``); returns its summary. An ``InputError`` is returned as a failure (running again
    cannot mend a bad input); any other exception is raised, for Ray to retry."""
    import torch

    from ray3d.jobs import run_job

    torch.set_num_threads(threads)
    started = time.perf_counter()
    target = out_dir / entry.name
    temporary = Path(tempfile.mkdtemp(prefix=f".{entry.name}.", dir=out_dir))
    try:
        job = entry.job()
        done = run_job(job, temporary / f"world{job.world_format}" if job.kind == "keypoints" else temporary,
                       progress=False)
        world, frames = done.world, done.inputs[0].frames
    except InputError as err:
        shutil.rmtree(temporary, ignore_errors=True)
        return {"status": "failed", "error": err.message, "seconds": time.perf_counter() - started}
    except BaseException:
        shutil.rmtree(temporary, ignore_errors=True)
        raise
    summary = {"status": "done", "frames": frames, "people": len(world.tracks),
               "seconds": round(time.perf_counter() - started, 3)}
    (temporary / DONE_FILE).write_text(json.dumps({"fingerprint": fingerprint, "input": str(entry.input), **summary},
                                                  indent=1))
    _move_into_place(temporary, target)
    return summary


def _move_into_place(temporary: Path, target: Path) -> None:
    """Rename the finished ``temporary`` folder to ``target``, replacing an older output of the same input."""
    if target.exists():
        old = target.with_name(f".{target.name}.old-{os.getpid()}")
        target.rename(old)
        temporary.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        temporary.rename(target)


def _up_to_date(target: Path, fingerprint: str) -> dict | None:
    try:
        done = json.loads((target / DONE_FILE).read_text())
    except (OSError, ValueError):
        return None
    return done if done.get("fingerprint") == fingerprint and done.get("status") == "done" else None


def _error_line(err: BaseException) -> str:
    cause = getattr(err, "cause", None) or err
    lines = [line for line in str(cause).strip().splitlines() if line.strip()]
    return f"{type(cause).__name__}: {lines[-1] if lines else ''}"[:300]


def run(manifest: str | Path, out: str | Path, address: str | None = None, workers: int | None = None,
        retries: int = 2, cpus_per_task: float = 1, gpus_per_task: float = 0, progress: bool = True) -> BatchReport:
    """Run every input of ``manifest`` (see ``ray3d.batch.manifest``) as a Ray task, outputs below ``out``.

    ``address``: an existing cluster (``"auto"``, ``"ray://HOST:10001"``); without it a local Ray with
    ``workers`` CPUs (default: all) is started for the job and stopped after it. ``workers`` also caps the
    tasks running at once on a cluster. Each task reserves ``cpus_per_task`` CPUs (its torch threads) and
    ``gpus_per_task`` GPUs. Returns the per-input reports; ``OUT/summary.csv`` lists them.
    """
    if workers is not None and workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}", arguments=("workers",))
    if retries < 0:
        raise InputError(f"retries must be 0 or more, got {retries}", arguments=("retries",))
    entries = read_manifest(manifest)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is a file; the batch output must be a folder", arguments=("out",))
    if any(out.resolve() == e.input.resolve() for e in entries):
        raise InputError(f"{out}: is also an input", arguments=("out",))
    fingerprints = {e.name: e.fingerprint() for e in entries}
    out.mkdir(parents=True, exist_ok=True)
    reports: dict[str, InputReport] = {}
    todo = []
    for entry in entries:
        for stale in out.glob(f".{entry.name}.*"):  # left by a killed job
            shutil.rmtree(stale, ignore_errors=True)
        done = _up_to_date(out / entry.name, fingerprints[entry.name])
        if done:
            reports[entry.name] = InputReport(entry.name, str(entry.input), "skipped", done.get("frames"),
                                              done.get("people"), done.get("seconds"))
        else:
            todo.append(entry)
    if todo:
        ray, started = start_ray(address, workers)
        try:
            task = ray.remote(num_cpus=cpus_per_task, num_gpus=gpus_per_task, max_retries=retries,
                              retry_exceptions=True)(process_entry)
            limit = workers or len(todo)
            waiting, running = list(todo), {}
            threads = max(1, int(cpus_per_task))
            with progress_bar(shown=progress, total=len(todo), desc="inputs", unit="input") as bar:
                while waiting or running:
                    while waiting and len(running) < limit:
                        entry = waiting.pop(0)
                        running[task.remote(entry, out.resolve(), fingerprints[entry.name], threads)] = entry
                    finished, _ = ray.wait(list(running), num_returns=1)
                    entry = running.pop(finished[0])
                    try:
                        result = ray.get(finished[0])
                    except Exception as err:  # failed on every attempt
                        result = {"status": "failed", "error": f"after {retries + 1} attempts: {_error_line(err)}"}
                    reports[entry.name] = InputReport(entry.name, str(entry.input), result["status"],
                                                      result.get("frames"), result.get("people"),
                                                      result.get("seconds"), result.get("error", ""))
                    bar.update()
        finally:
            if started:
                ray.shutdown()
    ordered = [reports[e.name] for e in entries]
    summary = out / SUMMARY_FILE
    text = io.StringIO()
    writer = csv.DictWriter(text, SUMMARY_FIELDS)
    writer.writeheader()
    writer.writerows(dataclasses.asdict(r) for r in ordered)
    with atomic_path(summary, overwrite=True) as temporary:
        temporary.write_text(text.getvalue())
    return BatchReport(ordered, summary)
