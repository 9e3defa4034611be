"""Metric curves: one line per method against a swept variable, as the paper's robustness figures."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ray3d.io.atomic import atomic_path  # noqa: E402


def plot_sweep_panels(x: list[float], panels: dict[str, dict[str, list[float]]], xlabel: str, title: str,
                      path: str | Path) -> Path:
    """One PNG with a panel per metric ({y-axis label: {method: values}}), one line per method."""
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), dpi=110, squeeze=False)
    for axis, (ylabel, curves) in zip(axes[0], panels.items()):
        for name, values in curves.items():
            axis.plot(x, values, marker="o", ms=3, label=name)
        axis.set_xlabel(xlabel)
        axis.set_ylabel(ylabel)
        axis.grid(alpha=0.3)
        axis.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path, overwrite=True) as temporary:
        fig.savefig(temporary, format="png")
    plt.close(fig)
    return path


def plot_sweep(x: list[float], curves: dict[str, list[float]], xlabel: str, ylabel: str, title: str,
               path: str | Path) -> Path:
    """A single-panel sweep plot."""
    return plot_sweep_panels(x, {ylabel: curves}, xlabel, title, path)
