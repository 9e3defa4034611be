"""Benchmarks: speed (and, later, robustness sweeps)."""
