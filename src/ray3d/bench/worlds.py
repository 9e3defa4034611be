"""Two world files of one scene compared track by track (``ray3d bench worlds``): two runs of the same video (a
camera file moved against the true one, one process against Ray) and how far apart they put the same people."""

from __future__ import annotations

import numpy as np

from ray3d.io.world import read_world
from ray3d.metrics import match_tracks

MIN_SHARE = 0.5  # a track's partner is among those seen in at least this share of its frames


def compare_worlds(first, second, min_share: float = MIN_SHARE) -> dict:
    """Each track of world file ``first`` matched to the track of world file ``second`` whose pelvis floor points
    lie nearest (``metrics.match_tracks``, in the world frame): tracks of each, tracks matched, the median over the
    matched tracks of their median distance and the largest (m), frames shared and frames of ``first``'s tracks."""
    a, b = (read_world(path).in_frame("world") for path in (first, second))
    matches = match_tracks(a.tracks, b.tracks, min_share)
    medians = [m.median_m for m in matches]
    return {"tracks": [len(a.tracks), len(b.tracks)], "matched": len(matches),
            "median_pelvis_floor_distance_m": round(float(np.median(medians)), 3) if medians else None,
            "largest_track_median_m": round(max(medians), 3) if medians else None,
            "frames_shared": sum(len(m.frames) for m in matches),
            "frames_first": sum(len(t.frames) for t in a.tracks.values())}
