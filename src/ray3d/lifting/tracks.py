"""Several tracks of a camera: on their way through the network (``CameraTracks``) and what lifting them gives
(``LiftedTracks``), put together from each track's outcome."""

from __future__ import annotations

import dataclasses

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.refine import AnklePlane


class LiftedTracks(dict):
    """{track id: LiftResult} of the tracks lifted, ``unliftable``: {track id: why} of those that could not be,
    and ``ankle_plane``: where their ankles meet the floor (``ray3d.refine.AnklePlane``; None unrefined)."""

    def __init__(self) -> None:
        super().__init__()
        self.unliftable: dict = {}
        self.ankle_plane: AnklePlane | None = None
        self.evidence: dict = {}  # {track id: its ``SizeEvidence`` of the ankle plane, None where it gave none}


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
    """One camera's tracks on their way through the network (``Lifter``): ``networks`` {track: (T, 17, 3) joints in the frame
    of the camera with its z = 0 moved to ``depth``, or the InputError that stopped it} and ``found`` {track: its
    ``SizeEvidence`` of the ankle plane, None where it gave none}."""

    prepared: dict
    camera: Camera
    progress: dict
    networks: dict = dataclasses.field(default_factory=dict)
    found: dict = dataclasses.field(default_factory=dict)
    depth: float = 0.0

    def lifted(self) -> bool:
        return any(not isinstance(joints, InputError) for joints in self.networks.values())
