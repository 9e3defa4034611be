"""Several tracks of a camera: made ready to lift (``prepared_tracks``), on their way through the network
(``CameraTracks``) and what lifting them gives (``LiftedTracks``), put together from each track's outcome."""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.arrays import numeric_array
from ray3d.io.detections import TrackDetections
from ray3d.lifting.inputs import prepare_track
from ray3d.lifting.options import LiftOptions
from ray3d.refine import AnklePlane
from ray3d.refine.ankle_plane import SeenTwice, seen_twice
from ray3d.skeleton import Skeleton


class LiftedTracks(dict):
    """{track id: LiftResult} of the tracks lifted, ``unliftable``: {track id: why} of those that could not be,
    and ``ankle_plane``: where their ankles meet the floor (``ray3d.refine.AnklePlane``; None unrefined)."""

    def __init__(self, evidence: dict | None = None, ankles: list | None = None) -> None:
        super().__init__()
        self.unliftable: dict = {}
        self.ankle_plane: AnklePlane | None = None
        # What these people showed of the floor itself (``refine.ankle_plane.floor_evidence``), for later lifts'
        # ``seen_before``: {track id: its ``SizeEvidence``, None where it gave none}, and the ``SeenTwice`` of
        # people this camera and another saw at once.
        self.evidence: dict = evidence if evidence is not None else {}
        self.ankles: list = ankles if ankles is not None else []

    def floor_evidence(self) -> tuple:
        """Everything these people showed of the floor, as a later lift's ``seen_before`` takes it."""
        return (*(e for e in self.evidence.values() if e is not None), *self.ankles)


def rows_with_gaps(frames, keypoints: np.ndarray, confidences) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``Lifter.lift``'s rows at ``frames``, their frame numbers -> (every frame number from the first to the last
    (T',), keypoints (T', J, 2) NaN and confidences (T', J) 0 in the frames skipped), as ``prepared_tracks`` fills a
    track's gaps (``TrackDetections.dense``). Refused: frame numbers that are not one per row, not whole numbers,
    or not increasing."""
    numbers, rows = numeric_array(frames, "frames"), len(keypoints) if keypoints.ndim else 0
    if numbers.ndim != 1 or len(numbers) != rows:
        raise InputError(f"frames: the frame number of each of the keypoints' {rows} rows expected, got "
                         f"shape {numbers.shape}", arguments=("frames",))
    if not (np.isfinite(numbers).all() and (numbers == np.round(numbers)).all()):
        raise InputError("frames: whole numbers expected", arguments=("frames",))
    if (np.diff(numbers) <= 0).any():
        row = int(np.flatnonzero(np.diff(numbers) <= 0)[0]) + 1
        raise InputError(f"frames: frame numbers must increase row by row; row {row} has {numbers[row]:.0f} after "
                         f"{numbers[row - 1]:.0f}", arguments=("frames",))
    if confidences is not None:
        scores = numeric_array(confidences, "confidences")
        if scores.shape != keypoints.shape[:2]:
            raise InputError(f"confidences: expected shape {keypoints.shape[:-1]}, got {scores.shape}",
                             arguments=("confidences",))
    return TrackDetections(numbers, keypoints, confidences).dense("frames")


def prepared_tracks(tracks: dict, camera: Camera, fps: float | None, layout: str, smooth_2d: str | None,
                    model_skeleton: Callable[[Skeleton], Skeleton]) -> tuple[dict, dict, dict]:
    """{track: detections, as ``Lifter.lift_tracks`` takes them} -> {track: its ``PreparedTrack`` for a model
    reading ``model_skeleton(skeleton)``}, {track: its frame span}, {track: the InputError refusing it}."""
    prepared, spans, failures = {}, {}, {}
    for track, entry in tracks.items():
        try:
            if not isinstance(entry, tuple) or len(entry) not in (2, 3):
                raise InputError(f"tracks[{track!r}]: expected (frame ids, pixels[, confidences])", ("tracks",))
            spans[track], pixels, confidences = TrackDetections(*entry).dense(f"tracks[{track!r}]")
            prepared[track] = prepare_track(pixels, camera, confidences, fps, layout, smooth_2d, model_skeleton)
        except InputError as err:
            failures[track] = err
    return prepared, spans, failures


def progress_labels(prepared: dict, shown: bool) -> dict:
    """Each track's progress bar label (or none)."""
    return {track: f"track {track}" if shown else False for track in prepared}


def gathered(results: LiftedTracks, tracks: dict, lifted: dict, spans: dict, failures: dict,
              plane: AnklePlane | None) -> LiftedTracks:
    """``results`` filled in the tracks' order from what was lifted and what failed; an InputError when nothing
    could be lifted."""
    for track in tracks:
        outcome = lifted.get(track, failures.get(track))
        if isinstance(outcome, InputError):
            failures[track] = outcome
        elif outcome is not None:
            results[track] = dataclasses.replace(outcome, frames=spans[track])
    results.unliftable = {track: err.message for track, err in failures.items()}
    results.ankle_plane = plane
    if not results and len(failures) == 1:
        raise next(iter(failures.values()))
    if not results:
        raise InputError("no track could be lifted: " + "; ".join(
            f"track {track}: {why}" for track, why in results.unliftable.items()))
    return results


@dataclasses.dataclass
class CameraTracks:
    """One camera's tracks on their way through the network (``Lifter``), lifted with its own ``options``:
    ``networks`` {track: (T, 17, 3)
    joints in the frame of the camera with its z = 0 moved to ``depth``, or the InputError that stopped it} and
    ``found`` {track: its ``SizeEvidence`` of the ankle plane, None where it gave none}, and ``ankles``, the
    ``SeenTwice`` of people it and another camera saw at once."""

    prepared: dict
    camera: Camera
    progress: dict
    options: LiftOptions = LiftOptions()
    networks: dict = dataclasses.field(default_factory=dict)
    found: dict = dataclasses.field(default_factory=dict)
    ankles: list = dataclasses.field(default_factory=list)
    depth: float = 0.0

    def lifted(self) -> bool:
        return any(not isinstance(joints, InputError) for joints in self.networks.values())


def people_seen_twice(views: list[tuple[CameraTracks, dict]]) -> list[SeenTwice]:
    """Every pair of tracks of two cameras (each a ``CameraTracks`` and {track: its frame ids}, on one clock) that
    is one person seen by both at once: where their planted ankles stand, triangulated (``seen_twice``). Any two
    rays of two cameras pass near each other somewhere, so each track is paired at most once per other camera,
    with the track whose pelvis rays pass nearest its own."""
    found = []
    for (first, first_spans), (second, second_spans) in itertools.combinations(views, 2):
        candidates = []
        for (a, entry_a), (b, entry_b) in itertools.product(first.prepared.items(), second.prepared.items()):
            shared, rows_a, rows_b = np.intersect1d(first_spans[a], second_spans[b], return_indices=True)
            if len(shared) == 0:
                continue
            crossing = seen_twice((first.camera.center, second.camera.center),
                                  (entry_a.rays[rows_a], entry_b.rays[rows_b]),
                                  (~entry_a.missing[rows_a], ~entry_b.missing[rows_b]), entry_a.fps)
            if crossing is not None:
                candidates.append((crossing.pelvis_gap_m, a, b, crossing))
        paired = set()
        for _, a, b, crossing in sorted(candidates, key=lambda candidate: candidate[0]):
            if ("first", a) not in paired and ("second", b) not in paired:
                paired |= {("first", a), ("second", b)}
                found.append(crossing)
    return found
