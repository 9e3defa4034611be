"""Sparse robust least squares: a soft L1 loss on the rows that may be outliers and squares on the others,
minimised by Gauss-Newton with iteratively reweighted least squares (what ``TrackProblem.solve`` runs)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu


def soft_l1_cost(residuals: np.ndarray, robust: np.ndarray, scale: float) -> float:
    """The loss of (R,) ``residuals``: soft L1 where ``robust`` (R,) holds, quadratic within ``scale`` and linear
    beyond; squares elsewhere."""
    scaled = (residuals / scale) ** 2
    return float(np.sum(np.where(robust, 2 * (np.sqrt(1 + scaled) - 1), scaled)))


def soft_l1_weights(residuals: np.ndarray, robust: np.ndarray, scale: float) -> np.ndarray:
    """(R,) the weights that make a weighted least-squares step a step of ``soft_l1_cost`` (1 on the squares)."""
    return np.where(robust, 1 / np.sqrt(1 + (residuals / scale) ** 2), 1.0)


def gauss_newton(residuals: Callable[[np.ndarray], np.ndarray],
                 jacobian: Callable[[np.ndarray], sparse.spmatrix],
                 cost: Callable[[np.ndarray], float], weights: Callable[[np.ndarray], np.ndarray],
                 start: np.ndarray, iterations: int = 50, tolerance: float = 1e-10) -> np.ndarray:
    """The x that minimises ``cost`` from ``start``: each step one sparse solve of the normal equations of the
    ``jacobian`` (R, N) with the robust ``weights`` (R,) of the ``residuals`` (R,) at x, halved until it does not
    raise the cost; stops when a step moves no column by more than ``tolerance``, or none can lower the cost."""
    x, current = start.copy(), cost(start)
    for _ in range(iterations):
        rows, slopes = residuals(x), jacobian(x)
        weight = weights(rows)
        normal = (slopes.T @ sparse.diags(weight) @ slopes).tocsc()
        step = splu(normal + sparse.eye(len(x), format="csc") * 1e-12).solve(-(slopes.T @ (weight * rows)))
        for _ in range(20):  # halve a step that does not lower the cost
            trial = cost(x + step)
            if trial <= current:
                break
            step = step / 2
        else:
            return x
        x, current = x + step, trial
        if np.abs(step).max() < tolerance:
            break
    return x
