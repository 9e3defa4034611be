"""A source skeleton (hierarchy + rest offsets) and forward kinematics vectorised over frames.

Both file formats end up here: BVH joints and ASF bones are nodes with a parent, a rest offset in the
parent's frame, and per-frame local rotations; FK gives every node's world position and rotation.
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass
class KinematicTree:
    """Nodes in topological order (parents before children).

    Attributes:
        names: node names; end points (BVH End Sites) are named ``"<parent>.end"``.
        parents: parent index per node, -1 for the root.
        offsets: (N, 3) rest translation of each node from its parent, in the parent's rotated frame.
    """

    names: list[str]
    parents: list[int]
    offsets: np.ndarray

    def index(self, name: str) -> int:
        return self.names.index(name)

    def descendants(self, node: int) -> list[int]:
        """``node`` and every node below it."""
        found = [node]
        for i, parent in enumerate(self.parents):
            if parent in found:
                found.append(i)
        return found

    def forward_kinematics(self, local_rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
        """World positions (F, N, 3) of every node.

        Args:
            local_rotations: (F, N, 3, 3) rotation of each node's frame relative to its parent's frame
                (identity for end points).
            translations: (F, N, 3) translation of each node from its parent, in the parent's frame
                (the rest offset, or the root's per-frame position).
        """
        frames, count = local_rotations.shape[:2]
        world_rotations = np.empty_like(local_rotations)
        positions = np.empty((frames, count, 3))
        for i, parent in enumerate(self.parents):
            if parent < 0:
                world_rotations[:, i] = local_rotations[:, i]
                positions[:, i] = translations[:, i]
            else:
                world_rotations[:, i] = world_rotations[:, parent] @ local_rotations[:, i]
                positions[:, i] = (positions[:, parent]
                                   + (world_rotations[:, parent] @ translations[:, i, :, None])[..., 0])
        return positions
