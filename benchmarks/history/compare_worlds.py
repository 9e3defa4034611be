"""Two world files of the same scene compared track by track: each track of the first matched to the track of the
second, among those seen in at least half its frames, whose pelvis floor points lie nearest (median over the
frames both have).

    python benchmarks/compare_worlds.py FIRST SECOND
"""

from __future__ import annotations

import sys

import numpy as np

from ray3d.io.world import read_world


def compare(first: str, second: str) -> dict:
    a, b = read_world(first).in_frame("world"), read_world(second).in_frame("world")
    rows = []
    for name, track in a.tracks.items():
        best = None
        for other_name, other in b.tracks.items():
            shared, rows_a, rows_b = np.intersect1d(track.frames, other.frames, return_indices=True)
            if 2 * len(shared) < len(track.frames):
                continue
            distance = float(np.median(np.linalg.norm(track.root[rows_a, :2] - other.root[rows_b, :2], axis=-1)))
            if best is None or distance < best[2]:
                best = (other_name, len(shared), distance)
        rows.append((name, *(best or (None, 0, np.inf))))
    matched = [r for r in rows if r[1] is not None]
    return {"tracks": (len(a.tracks), len(b.tracks)), "matched": len(matched),
            "median_pelvis_floor_distance_m": float(np.median([r[3] for r in matched])) if matched else None,
            "largest_track_median_m": float(max(r[3] for r in matched)) if matched else None,
            "frames_shared": sum(r[2] for r in matched), "frames_first": sum(len(t.frames) for t in a.tracks.values())}


if __name__ == "__main__":
    print(compare(sys.argv[1], sys.argv[2]))
