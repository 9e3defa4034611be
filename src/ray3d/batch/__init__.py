"""Batch jobs: a manifest of videos and keypoint files, each input one task on a Ray cluster (or a local Ray),
resumable and fault-isolated (``pip install 'ray3d[cluster]'``)."""

from ray3d.batch.manifest import Entry, read_manifest
from ray3d.batch.runner import BatchReport, InputReport, run

__all__ = ["BatchReport", "Entry", "InputReport", "read_manifest", "run"]
