"""Motion data: the shipped mocap and its split, importers, dataset formats, virtual cameras, samples."""

from ray3d.data.importers import ImportedClip, import_amc, import_bvh
from ray3d.data.motion import MotionSet, load_shipped, select_split, split_of

__all__ = ["ImportedClip", "MotionSet", "import_amc", "import_bvh", "load_shipped", "select_split", "split_of"]
