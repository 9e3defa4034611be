"""Two world files of the same scene compared track by track (the history's "people moving 0.54 / 0.55 m on the
floor plan against the true camera's run"). Now ``ray3d bench worlds FIRST SECOND`` (``ray3d.bench.worlds``, on
``metrics.match_tracks``); this is the command the history's figures name, kept running.

    python benchmarks/history/compare_worlds.py FIRST SECOND
"""

from __future__ import annotations

import sys

from ray3d.bench.worlds import compare_worlds

if __name__ == "__main__":
    print(compare_worlds(sys.argv[1], sys.argv[2]))
