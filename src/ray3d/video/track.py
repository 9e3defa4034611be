"""A person followed through a video: the one record of who was seen where, from the tracker to lifting, the
world file and the events."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.io.detections import TrackDetections
from ray3d.video.detectors import Detection


@dataclasses.dataclass
class Track:
    """One person: the frame indices they were detected in, their detections there, where each put them on the
    floor (x, y metres; NaN where the camera could not) with that point's covariance (2, 2), their clothes'
    colours (hue-saturation histograms of the torso and the legs), the tracker's latest reading of their walk
    (``walk``: vx, vy in m/s) and the gaps across which it was taken up again (``rejoins``: one person, the frames
    between unseen)."""

    id: str  # the one type of a track id, from here to the world file and the events
    frames: list[int] = dataclasses.field(default_factory=list)
    detections: list[Detection] = dataclasses.field(default_factory=list)
    floor: list[np.ndarray] = dataclasses.field(default_factory=list)
    colour: np.ndarray | None = None
    floor_noise: list[np.ndarray] = dataclasses.field(default_factory=list)
    rejoins: list = dataclasses.field(default_factory=list)  # the ``identities.Rejoin``s that made it, in order
    walk: np.ndarray | None = None
    carried: bool = False  # a person in view when an earlier run on the stream was cut off, taken up by this track

    def seconds(self, fps: float) -> float:
        """How long the person was followed, first to last frame."""
        return (self.frames[-1] - self.frames[0] + 1) / fps

    def too_short(self, fps: float, shortest_s: float) -> str | None:
        """Why the track is left out of the people reported (followed for less than ``shortest_s``: a box on two
        people or on part of one as often as a person), or None when it is kept. The one rule, offline and live. A
        ``carried`` track is kept whatever its length: the person was followed before the cut, and the run cut off
        never finished them (their only record is this part)."""
        seconds = self.seconds(fps)
        return f"seen for {seconds:.2f} s (under {shortest_s:.2f} s)" if seconds < shortest_s and not self.carried \
            else None

    def as_detections(self) -> TrackDetections:
        """The frames, pixels and confidences as one record (what lifting reads)."""
        return TrackDetections(np.array(self.frames), np.stack([d.pixels for d in self.detections]),
                               np.stack([d.confidences for d in self.detections]))
