"""The options of a lifting job, as records built in one place: what ``ray3d lift``, ``ray3d video``, batch
manifests and every later command pass down to ``Lifter`` and ``lift_video``. Each checks its values when it is
made, so a bad option is refused before any work starts."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry.floor import FLAT_FLOOR, Floor, checked_floor_z
from ray3d.io.world import check_frame
from ray3d.refine import RefineConfig
from ray3d.refine.ankle_plane import checked_evidence
from ray3d.temporal import OUTPUT_SMOOTHING, SMOOTHING_METHODS


def _smoothing(name: str, value: str | None) -> str | None:
    """A smoothing method, "none" (or None) for none."""
    if value is None or value == "none":
        return None
    if value not in SMOOTHING_METHODS:
        raise InputError(f"{name}: unknown smoothing {value!r}; one of {', '.join(SMOOTHING_METHODS)} or none",
                         arguments=(name,))
    return value


@dataclasses.dataclass(frozen=True)
class LiftOptions:
    """How keypoints become world joints: ``smooth_2d`` / ``smooth_3d`` the input pixels / output joints in
    time ("savgol", "one-euro" or None / "none"), ``flip_test``, ``refine`` (the track-level refinement: True,
    False or a ``RefineConfig``), the ``frame`` the written joints are in ("world" or "camera") and the ``floor``
    the refinement rests the feet on (``ray3d.geometry.floor``: z = 0 unless regions are declared), and
    ``floor_z``, where the floor lies in the camera's frame (None: decided on the people,
    ``ray3d.refine.ankle_plane``), with what the camera's people showed of it before (``seen_before``: the
    ``SizeEvidence`` and ``SeenTwice`` of earlier lifts, ``LiftedTracks.evidence`` and ``ankles``)."""

    smooth_2d: str | None = None
    smooth_3d: str | None = OUTPUT_SMOOTHING
    flip_test: bool = False
    refine: bool | RefineConfig = True
    frame: str = "world"
    floor: Floor = FLAT_FLOOR
    floor_z: float | None = None
    seen_before: tuple = ()

    def __post_init__(self) -> None:
        if self.floor_z is not None:
            object.__setattr__(self, "floor_z", checked_floor_z(self.floor_z))
        object.__setattr__(self, "seen_before", checked_evidence(self.seen_before))
        object.__setattr__(self, "smooth_2d", _smoothing("smooth_2d", self.smooth_2d))
        object.__setattr__(self, "smooth_3d", _smoothing("smooth_3d", self.smooth_3d))
        check_frame(self.frame)

    def lift_arguments(self) -> dict:
        """The keyword arguments of ``Lifter.lift`` these options set."""
        return {"smooth_2d": self.smooth_2d, "smooth_3d": self.smooth_3d, "flip_test": self.flip_test,
                "refine": self.refine, "floor": self.floor, "floor_z": self.floor_z, "seen_before": self.seen_before}


@dataclasses.dataclass(frozen=True)
class VideoOptions:
    """Which part of a video, and how people are followed: ``fps`` overrides the rate the video reports,
    ``start`` / ``frames`` select frames, a person unseen for longer than ``max_gap_s`` starts a new track, which
    continues theirs when it starts within ``rejoin_s`` where their walk led in the same clothes
    (``video.identities``; 0: never), and tracks shorter than ``min_track_s`` are dropped."""

    fps: float | None = None
    start: int = 0
    frames: int | None = None
    max_gap_s: float = 0.5
    min_track_s: float = 1.0
    rejoin_s: float = 3.0

    def __post_init__(self) -> None:
        for name in ("max_gap_s", "min_track_s", "rejoin_s"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name} must be a duration in seconds, 0 or more; got {value}", arguments=(name,))
        if self.start < 0:
            raise InputError(f"start must be a frame index, 0 or more; got {self.start}", arguments=("start",))
        if self.frames is not None and self.frames < 1:
            raise InputError(f"frames must be at least 1, got {self.frames}", arguments=("frames",))
