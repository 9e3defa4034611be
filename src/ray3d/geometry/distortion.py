"""OpenCV's lens distortion model (k1, k2, p1, p2, k3) on normalized image coordinates, and its inverse.

Written vectorised for numpy and torch so that it broadcasts over batches of cameras and keeps autograd;
OpenCV's ``projectPoints`` / ``undistortPoints`` are the test oracles. For numpy points of one camera the
inversion starts from OpenCV's (compiled, a few microseconds for a frame's joints) and Newton's method only
polishes it to full precision, in one or two steps instead of four or more from the distorted point.
"""

from __future__ import annotations

import numpy as np
import torch

from ray3d.geometry.arrays import Array, namespace, stack_last

UNDISTORT_ITERATIONS = 20
UNDISTORT_TOLERANCE = 1e-10  # squared residual (normalized units) above which a point has not converged
_OPENCV_CRITERIA = (3, UNDISTORT_ITERATIONS, 1e-15)  # cv2.TERM_CRITERIA_COUNT | EPS: iterations, step size


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


def opencv_undistort(xy_distorted: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(..., 2) distorted normalized coordinates of one camera with (5,) coefficients -> OpenCV's inverse
    (``cv2.undistortPoints``' fixed-point iteration, run to full float64 precision where it converges)."""
    import cv2

    flat = np.ascontiguousarray(xy_distorted, dtype=np.float64).reshape(-1, 1, 2)
    if flat.size == 0:
        return np.array(xy_distorted, dtype=np.float64)
    ideal = cv2.undistortPoints(flat, np.eye(3), np.asarray(dist, dtype=np.float64), R=None, P=None,
                                criteria=_OPENCV_CRITERIA)
    return ideal.reshape(np.shape(xy_distorted))


def _jacobian(x: Array, y: Array, dist: Array):
    """(radial, j11, j12, j22) of :func:`distort` at (x, y): its symmetric 2x2 Jacobian."""
    k1, k2, p1, p2, k3 = _split(dist)
    r2 = x * x + y * y
    radial, slope = _radial_and_slope(r2, k1, k2, k3)
    j11 = radial + 2 * x * x * slope + 2 * p1 * y + 6 * p2 * x
    j12 = 2 * x * y * slope + 2 * p1 * x + 2 * p2 * y
    j22 = radial + 2 * y * y * slope + 6 * p1 * y + 2 * p2 * x
    return radial, j11, j12, j22


def undistort(xy_distorted: Array, dist: Array, initial: Array | None = None,
              iterations: int = UNDISTORT_ITERATIONS) -> Array:
    """Invert :func:`distort`: Newton's method on the 2x2 system, or for numpy points of one camera OpenCV's
    inversion, polished by Newton's method where it did not reach full precision.

    Args:
        xy_distorted: (..., 2) distorted normalized coordinates.
        dist: (..., 5) OpenCV coefficients, broadcastable against the leading axes.
        initial: optional (..., 2) starting guess (default: OpenCV's inverse for numpy points of one camera,
            else the distorted point itself); a close guess (e.g. the clean point before 2D noise was added)
            needs only a few ``iterations``.

    Returns:
        (..., 2) ideal normalized coordinates. Points where the model is not invertible (far outside the
        calibrated field of view, where the polynomial folds back) come out as NaN.
    """
    xp = namespace(xy_distorted)
    xd, yd = xy_distorted[..., 0], xy_distorted[..., 1]
    tolerance = _step_tolerance(xd)
    residual = None  # of the start, when it needs no polish
    if initial is None and isinstance(xy_distorted, np.ndarray) and np.ndim(dist) == 1:
        initial = opencv_undistort(xy_distorted, dist)
        residual = distort(initial, dist) - xy_distorted
        if bool((abs(residual) > tolerance).any()):  # not at full precision everywhere (NaN counts as done)
            residual = None
        else:
            iterations = 0
    x, y = (xd, yd) if initial is None else (initial[..., 0], initial[..., 1])
    k1, k2, p1, p2, k3 = _split(dist)
    for _ in range(iterations):
        r2 = x * x + y * y
        radial, j11, j12, j22 = _jacobian(x, y, dist)
        fx = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd
        fy = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - yd
        det = j11 * j22 - j12 * j12
        step_x, step_y = (j22 * fx - j12 * fy) / det, (j11 * fy - j12 * fx) / det
        x, y = x - step_x, y - step_y
        # Newton converges quadratically: once no step exceeds a few ulps more iterations change nothing (a
        # live stream's 17 points took 20 iterations of ~40 operations each). NaN steps count as done.
        if not bool((abs(step_x) + abs(step_y) > tolerance).any()):
            break
    _, j11, j12, j22 = _jacobian(x, y, dist)
    if residual is None:
        residual = distort(stack_last([x, y]), dist) - xy_distorted
    # Beyond the fold the Jacobian's determinant turns negative: such a root is not the physical ray.
    converged = ((residual * residual).sum(-1) < UNDISTORT_TOLERANCE) & (j11 * j22 - j12 * j12 > 0)
    nan = xp.full_like(x, float("nan"))
    return stack_last([xp.where(converged, x, nan), xp.where(converged, y, nan)])
