"""Live on Ray: each camera in a Ray actor of its own (``CameraWorker``: its stream read and decoded there, its
people detected, tracked and lifted there, the tracks it lets go lifted offline there), placed by the cluster with
the CPUs it states. Only its people per frame come back (a few kilobytes), to ``RayCameras``, which the run's loop
(``live.runner.follow``) reads as it reads cameras followed in this process: the events, the page and the world
files are made the same way.

Faults: a worker that dies is started again and takes its stream up where it was left (a file: from the frame
after the last one processed, or, played at its rate, from where the play has got to; a camera or a stream: where
it is now); the frames it missed are said once, as a dropped stretch, and the people it was following end there.
A stream that ends, stalls or breaks off ends its worker. One step of each worker is in flight at a time: a worker
keeps only its newest frames (those pushed out counted per camera), so nothing queues between the actors and
this process. Files read as fast as they are processed are taken in the order of their frames' times, as in
this process (``live.source.SourceGroup``): each worker's answer is held until every other's is in, whichever
actor was quicker, so that the cameras' people are joined at the moments they were seen; one camera steps at a
time then, as in this process (files to get through faster on a cluster: play them at their rate, or ``ray3d
batch``).

The cameras' lifts pool what their people show of the run's one floor (``live.floor.FloorPool``) through a pool
in a Ray actor of its own (``RemoteFloorPool``), which the run's loop adds the people two cameras saw at once to."""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable

from ray3d.errors import InputError
from ray3d.live.cameras import CameraPeople, Finished, FrameResult
from ray3d.live.floor import FloorPool
from ray3d.live.source import StreamStalled

STEP_WAIT_S = 0.25  # how often the loop looks up from waiting for the workers (a signal, a closed run)


class CameraWorker:
    """One camera, run in a Ray actor: ``opened(first_index)`` opens its stream, camera and detector
    (``jobs.live.open_stream``), ``lifter(layout)`` gives its lifter (``jobs.Job.lifter``).
    ``step()`` -> its next frame's ``FrameResult`` (``arrived``: the frame's age in seconds; ``counts``: frames read,
    dropped and people postponed so far), or ``(ending, why)`` once its stream has ended, stalled or broken off."""

    def __init__(self, opened: Callable, lifter: Callable, lift_options, following,
                 first_index: int = 0, id_prefix: str = "", floor: RemoteFloorPool | None = None, carried=()):
        import torch

        torch.set_num_threads(1)
        self.source, self.camera, detector = opened(first_index=first_index)
        self.people = CameraPeople(self.camera, detector, lifter(detector.layout), self.source.fps,
                                   self.source.deadline_frames, lift_options, following, id_prefix,
                                   floor, carried)

    def describe(self) -> tuple:
        return self.camera, self.source.fps, self.source.name

    def step(self):
        try:
            frame = self.source.next()
        except StreamStalled as err:
            return "stalled", err.message
        except InputError as err:
            return "broke off", err.message
        if frame is None:
            return "ended", f"{self.source.name}: the stream ended"
        result = self.people.process(frame)
        self.source.stride = result.stride
        result.arrived = time.monotonic() - frame.arrived
        result.counts = (self.source.read, self.source.dropped, self.people.postponed())
        return result

    def close_source(self) -> None:
        self.source.close()

    def finish(self):
        """Everybody still in view let go and lifted (``CameraPeople.finish``)."""
        self.source.close()
        return self.people.finish()


class RemoteFloorPool:
    """A run's ``FloorPool`` in a Ray actor, as the camera workers and the run's loop reach it (the same calls).
    A pool that cannot be reached gives nothing and takes nothing: the cameras lift on what they have."""

    def __init__(self, actor):
        self.actor = actor

    def remember(self, evidence) -> None:
        self._call("remember", tuple(evidence))

    def add(self, evidence) -> None:
        self._call("add", tuple(evidence))

    def evidence(self) -> tuple:
        import ray

        return self._call("evidence", wait=ray.get) or ()

    def _call(self, name: str, *arguments, wait=lambda ref: None):
        import ray

        try:
            return wait(getattr(self.actor, name).remote(*arguments))
        except ray.exceptions.RayError:  # the pool gone (the run ending): nothing to add to, nothing to give
            return None


@dataclasses.dataclass
class _Worker:
    arguments: dict
    actor: object
    source: str
    played: bool
    name: str = ""
    last_index: int = -1
    last_seen: float = 0.0
    ended: tuple | None = None
    restarts: int = 0
    in_view: set = dataclasses.field(default_factory=set)
    counts: tuple = (0, 0, 0)      # this incarnation's frames read, dropped, people postponed
    before: tuple = (0, 0, 0)      # those of the incarnations that died
    run_prefix: str = ""           # the run's track id prefix, before each restart's


class _TimeOrder:
    """The answers of cameras reading files as fast as they are processed (``held``: camera -> its answer), each
    held until every other open camera's is in, then handed out in the order of their frames' times on the first
    camera's clock (``offsets_s``: each camera's clock ahead of the first's, ``live.source.SourceGroup``'s), the
    first camera's at a tie."""

    def __init__(self, fps: list[float]):
        self.fps, self.offsets_s, self.held = fps, [0.0] * len(fps), {}

    def earliest(self, ended: list[bool]) -> int | None:
        """The camera whose answer is handed out next; None while an open camera's (not ``ended``) is not in."""
        if not self.held or not all(view in self.held or done for view, done in enumerate(ended)):
            return None
        return min(self.held, key=lambda view: (self.held[view].index / self.fps[view] - self.offsets_s[view], view))


def _described(ray, worker: _Worker, actors: list) -> tuple:
    """A worker's (camera, fps, name), or every one of the run's ``actors`` stopped and an ``InputError`` saying
    why it could not start."""
    try:
        return ray.get(worker.actor.describe.remote())
    except ray.exceptions.RayError as err:
        for actor in actors:
            ray.kill(actor)
        cause = getattr(err, "cause", None)
        if isinstance(cause, InputError):
            raise InputError(cause.message, cause.arguments) from None
        lines = [line for line in str(err).splitlines() if line.strip()]
        raise InputError(f"{worker.source}: its camera worker could not start "
                         f"({lines[-1] if lines else type(err).__name__})", ("source",)) from None


class RayCameras:
    """Every camera in a ``CameraWorker`` actor on the initialised ``ray``, each reserving ``cpus_per_camera``;
    a worker that dies is started again up to ``restarts`` times. Per camera: ``CameraWorker``'s keyword
    ``arguments``, its ``sources`` (as the user named it) and whether it is ``played`` on while nobody reads it (a
    camera, a stream, a file at its rate). ``report`` is told of each dropped stretch."""

    def __init__(self, ray, arguments: list[dict], sources: list[str], played: list[bool],
                 cpus_per_camera: float = 1.0, restarts: int = 3,
                 report: Callable[[str], None] = lambda line: print(line, file=sys.stderr)):
        self.ray, self.restarts, self.report = ray, restarts, report
        self.sources = [str(source) for source in sources]
        self._remote = ray.remote(num_cpus=cpus_per_camera, max_restarts=0, max_concurrency=2)(CameraWorker)
        # One floor for every camera of the run (a worker started again finds it as it was).
        self.floor = RemoteFloorPool(ray.remote(num_cpus=0)(FloorPool).remote())
        arguments = [{**a, "floor": self.floor} for a in arguments]
        self.workers = [_Worker(dict(a), self._remote.remote(**a), str(source), on, run_prefix=a.get("id_prefix", ""))
                        for a, source, on in zip(arguments, sources, played)]
        described = [_described(ray, worker, [w.actor for w in self.workers] + [self.floor.actor])
                     for worker in self.workers]
        self.cameras = [camera for camera, _, _ in described]
        self.fps = [fps for _, fps, _ in described]
        self.names = [camera.name or name for camera, _, name in described]
        for worker, name in zip(self.workers, self.names):
            worker.name, worker.last_seen = name, time.monotonic()
        self.name = " + ".join(name for _, _, name in described)
        self.dropped_stretches: list[str] = []
        self._closed = False
        self._in_flight = {worker.actor.step.remote(): view for view, worker in enumerate(self.workers)}
        self._order = _TimeOrder(self.fps)

    def set_clocks(self, offsets_s: list[float]) -> None:
        self._order.offsets_s = list(offsets_s)

    def next(self) -> tuple[int, FrameResult] | None:
        while (self._in_flight or self._order.held) and not self._closed:
            if (view := self._order.earliest([w.ended is not None for w in self.workers])) is not None:
                worker = self.workers[view]  # its answer handed out, it steps on
                self._in_flight[worker.actor.step.remote()] = view
                return view, self._taken(worker, self._order.held.pop(view))
            if not self._in_flight:
                break
            ready, _ = self.ray.wait(list(self._in_flight), num_returns=1, timeout=STEP_WAIT_S)
            if not ready:
                continue
            view = self._in_flight.pop(ready[0])
            worker = self.workers[view]
            try:
                out = self.ray.get(ready[0])
            except self.ray.exceptions.RayActorError:
                lost = self._start_again(view)
                if lost is not None:
                    return view, lost
                continue
            if isinstance(out, tuple):
                worker.ended = out
                continue
            if not any(w.played for w in self.workers if w.ended is None):  # files read as fast as processed
                self._order.held[view] = out
                continue
            self._in_flight[worker.actor.step.remote()] = view
            return view, self._taken(worker, out)
        if self._closed:
            return None
        endings = {kind: why for kind, why in (w.ended for w in self.workers if w.ended)}
        if "stalled" in endings:
            error = StreamStalled(self.name, 0.0)
            error.message = endings["stalled"]
            raise error
        if "broke off" in endings:
            raise InputError(endings["broke off"], ("source",))
        return None

    def _taken(self, worker: _Worker, result: FrameResult) -> FrameResult:
        result.arrived = time.monotonic() - result.arrived  # its age there, as an arrival on this clock
        worker.last_index, worker.last_seen, worker.counts = result.index, time.monotonic(), result.counts
        worker.in_view = (worker.in_view | {p.track for p in result.persons}) - set(result.ended)
        return result

    def _start_again(self, view: int) -> FrameResult | None:
        """A worker that died, started again where its stream was left; the people it followed end (a result of
        their ending, None when it followed nobody)."""
        worker = self.workers[view]
        worker.restarts += 1
        worker.before = tuple(a + b for a, b in zip(worker.before, worker.counts))
        worker.counts = (0, 0, 0)
        lost, worker.in_view = sorted(worker.in_view), set()
        if worker.restarts > self.restarts:
            worker.ended = ("broke off", f"{worker.name}: its camera worker died {worker.restarts} times")
        else:
            arguments = worker.arguments
            # A stream, or a file played at its rate, went on meanwhile; a file read as fast as it decodes waited.
            missed = int(round((time.monotonic() - worker.last_seen) * self.fps[view])) if worker.played else 0
            first = max(arguments.get("first_index", 0), worker.last_index + 1 + missed)
            arguments.update(first_index=first, id_prefix=f"{worker.run_prefix}r{worker.restarts}-", carried=())
            worker.actor = self._remote.remote(**arguments)
            self._in_flight[worker.actor.step.remote()] = view
            line = (f"{worker.name}: its camera worker stopped after frame {worker.last_index} and was started "
                    f"again from frame {first}" + (f": frames {worker.last_index + 1}-{first - 1} dropped" if missed
                                                   else ""))
            self.dropped_stretches.append(line)
            self.report(line)
        return FrameResult(worker.last_index, time.monotonic(), [], lost, []) if lost else None

    def finish(self) -> list[tuple[list[tuple[str, int]], list[Finished]]]:
        """Every worker's stream closed and everybody still in view let go and lifted; the workers stopped."""
        for worker in self.workers:
            if worker.ended is None:
                worker.actor.close_source.remote()
        swallowed: dict[int, list[FrameResult]] = {}
        for view, result in self._order.held.items():  # answers held for the others' when the run stopped
            swallowed.setdefault(view, []).append(self._taken(self.workers[view], result))
        self._order.held = {}
        for ref, view in self._in_flight.items():  # steps under way when the run stopped
            try:
                out = self.ray.get(ref)
            except self.ray.exceptions.RayError:
                continue
            if isinstance(out, FrameResult):
                swallowed.setdefault(view, []).append(self._taken(self.workers[view], out))
        self._in_flight = {}
        results = []
        for view, worker in enumerate(self.workers):
            done = [finished for result in swallowed.get(view, []) for finished in result.done]
            let_go = [(track, result.index) for result in swallowed.get(view, []) for track in result.ended]
            try:
                in_view, left = self.ray.get(worker.actor.finish.remote())
            except self.ray.exceptions.RayError:
                in_view, left = [], []
            followed = {track for track, _ in in_view}
            in_view += let_go + [(track, worker.last_index) for track in sorted(worker.in_view - followed)]
            results.append((in_view, done + left))
            self.ray.kill(worker.actor)
        self.ray.kill(self.floor.actor)
        return results

    @property
    def read(self) -> int:
        return sum(w.before[0] + w.counts[0] for w in self.workers)

    @property
    def dropped(self) -> int:
        return sum(w.before[1] + w.counts[1] for w in self.workers)

    @property
    def postponed(self) -> int:
        return sum(w.before[2] + w.counts[2] for w in self.workers)

    def close(self) -> None:
        """Stop taking frames (safe in a signal handler: the loop sees it within ``STEP_WAIT_S``)."""
        self._closed = True
