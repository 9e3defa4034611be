"""File formats in and out: atomic writes, dataset formats, exports."""
