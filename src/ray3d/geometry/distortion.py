"""OpenCV's lens distortion model (k1, k2, p1, p2, k3) on normalized image coordinates, and its inverse.

Written vectorised for numpy and torch so that it broadcasts over batches of cameras and keeps autograd;
OpenCV's ``projectPoints`` / ``undistortPoints`` are the test oracles.
"""

from __future__ import annotations

import numpy as np
import torch

from ray3d.geometry.arrays import Array, namespace, stack_last

UNDISTORT_ITERATIONS = 20
UNDISTORT_TOLERANCE = 1e-10  # squared residual (normalized units) above which a point has not converged


def _step_tolerance(x: Array) -> float:
    """A few units in the last place of normalized coordinates (order 1) in ``x``'s precision."""
    dtype = x.dtype
    eps = torch.finfo(dtype).eps if isinstance(x, torch.Tensor) else np.finfo(dtype).eps
    return 8 * float(eps)


def _split(dist: Array):
    return (dist[..., i] for i in range(5))


def _radial_and_slope(r2: Array, k1: Array, k2: Array, k3: Array):
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    slope = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    return radial, slope


def distort(xy: Array, dist: Array) -> Array:
    """Apply lens distortion to ideal normalized coordinates.

    Args:
        xy: (..., 2) ideal normalized image coordinates (x / z, y / z).
        dist: (..., 5) OpenCV coefficients k1, k2, p1, p2, k3, broadcastable against ``xy``'s leading axes.

    Returns:
        (..., 2) distorted normalized coordinates.
    """
    x, y = xy[..., 0], xy[..., 1]
    k1, k2, p1, p2, k3 = _split(dist)
    r2 = x * x + y * y
    radial, _ = _radial_and_slope(r2, k1, k2, k3)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return stack_last([xd, yd])


def undistort(xy_distorted: Array, dist: Array, initial: Array | None = None,
              iterations: int = UNDISTORT_ITERATIONS) -> Array:
    """Invert :func:`distort` by Newton's method on the 2x2 system.

    Args:
        xy_distorted: (..., 2) distorted normalized coordinates.
        dist: (..., 5) OpenCV coefficients, broadcastable against the leading axes.
        initial: optional (..., 2) starting guess (default: the distorted point itself); a close guess
            (e.g. the clean point before 2D noise was added) needs only a few ``iterations``.

    Returns:
        (..., 2) ideal normalized coordinates. Points where the model is not invertible (far outside the
        calibrated field of view, where the polynomial folds back) come out as NaN.
    """
    xp = namespace(xy_distorted)
    k1, k2, p1, p2, k3 = _split(dist)
    xd, yd = xy_distorted[..., 0], xy_distorted[..., 1]
    x, y = (xd, yd) if initial is None else (initial[..., 0], initial[..., 1])
    tolerance = _step_tolerance(x)
    for _ in range(iterations):
        r2 = x * x + y * y
        radial, slope = _radial_and_slope(r2, k1, k2, k3)
        fx = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd
        fy = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - yd
        j11 = radial + 2 * x * x * slope + 2 * p1 * y + 6 * p2 * x
        j12 = 2 * x * y * slope + 2 * p1 * x + 2 * p2 * y
        j22 = radial + 2 * y * y * slope + 6 * p1 * y + 2 * p2 * x
        det = j11 * j22 - j12 * j12  # the Jacobian is symmetric: j21 == j12
        step_x, step_y = (j22 * fx - j12 * fy) / det, (j11 * fy - j12 * fx) / det
        x, y = x - step_x, y - step_y
        # Newton converges quadratically: once no step exceeds a few ulps more iterations change nothing (a
        # live stream's 17 points took 20 iterations of ~40 operations each). NaN steps count as done.
        if not bool((abs(step_x) + abs(step_y) > tolerance).any()):
            break
    residual = distort(stack_last([x, y]), dist) - xy_distorted
    # Beyond the fold the Jacobian's determinant turns negative: such a root is not the physical ray.
    converged = ((residual * residual).sum(-1) < UNDISTORT_TOLERANCE) & (det > 0)
    nan = xp.full_like(x, float("nan"))
    return stack_last([xp.where(converged, x, nan), xp.where(converged, y, nan)])
