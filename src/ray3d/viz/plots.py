"""Metric curves: one line per method against a swept variable, as the paper's robustness figures."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ray3d.io.atomic import atomic_path  # noqa: E402


def plot_sweep(x: list[float], curves: dict[str, list[float]], xlabel: str, ylabel: str, title: str,
               path: str | Path, overwrite: bool = True) -> Path:
    """A PNG with one line per method."""
    fig, axes = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for name, values in curves.items():
        axes.plot(x, values, marker="o", ms=3, label=name)
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    axes.set_title(title)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path, overwrite) as temporary:
        fig.savefig(temporary, format="png")
    plt.close(fig)
    return path
