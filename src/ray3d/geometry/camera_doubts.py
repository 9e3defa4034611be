"""What makes a valid camera doubtful (``Camera.doubts``): a lens whose rays cannot be recovered inside its image
makes it unusable; a lens or a view nobody films people on a floor with makes it implausible. Each doubt is a clause
naming the camera (its ``label``), for the caller to print or to refuse with."""

from __future__ import annotations

import numpy as np

# A camera whose optical axis rises more than this above the horizontal is doubted: people are filmed from above
# or level with them, and a pitch typed with the wrong sign (positive looks down) looks up.
LOOKS_UP_DEG = 5.0


def lens_doubts(label: str, intrinsics: np.ndarray, dist: np.ndarray,
                image_size: tuple[int, int]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(unusable, implausible) from the lens alone: ``intrinsics`` (4,) fx, fy, cx, cy and ``dist`` (5,) OpenCV
    k1, k2, p1, p2, k3 over an image of ``image_size`` (width, height) pixels. Unusable: a distortion that turns back
    inside the image. Implausible: a field of view across the image under 3 or over 170 degrees; a principal point
    more than an image's size outside it."""
    width, height = image_size
    fx, fy, cx, cy = intrinsics
    corners = (np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float) - [cx, cy]) / [fx, fy]
    reach = float(np.linalg.norm(corners, axis=-1).max())  # the distorted radius the image reaches
    k1, k2, _, _, k3 = (float(v) for v in dist)
    radius = np.linspace(0.0, max(4 * reach, 4.0), 4001)
    distorted = radius * (1 + k1 * radius ** 2 + k2 * radius ** 4 + k3 * radius ** 6)
    turning = np.flatnonzero(np.diff(distorted) <= 0)
    if len(turning) and distorted[turning[0]] < reach:
        return (f"{label}'s lens distortion (k1 {k1:g}, k2 {k2:g}, k3 {k3:g}) turns back "
                f"{distorted[turning[0]]:.2f} focal lengths from the centre, inside the image (which reaches "
                f"{reach:.2f}): its rays cannot be recovered there",), ()
    doubts = []
    across = 2 * np.degrees(np.arctan(radius[np.searchsorted(distorted, max(cx, width - cx) / fx)]))
    if not 3.0 <= across <= 170.0:
        doubts.append(f"{label} sees {across:.1f} degrees across its image (focal {fx:g} px, k1 {k1:g}): no lens "
                      "people are filmed with")
    if not (-width <= cx <= 2 * width and -height <= cy <= 2 * height):
        doubts.append(f"{label}'s principal point ({cx:g}, {cy:g}) lies far outside its {width}x{height} image")
    return (), tuple(doubts)


def view_doubts(label: str, height_m: float, pitch: float, bottom_row_directions: np.ndarray) -> tuple[str, ...]:
    """What is implausible in the view of a camera ``height_m`` above the floor, pitched ``pitch`` radians down,
    whose image's bottom row looks along ``bottom_row_directions`` (N, 3) in the world: a bottom row looking above
    the horizon (the floor where people stand unseen); else an optical axis rising more than ``LOOKS_UP_DEG`` (a
    pitch of the wrong sign)."""
    if np.all(bottom_row_directions[:, 2] >= 0):
        return (f"{label} ({height_m:.2f} m high, pitch {np.degrees(pitch):+.0f} degrees) looks above the horizon at "
                "the bottom of its image: the floor where people stand is not in view (positive pitch looks down)",)
    if np.degrees(pitch) < -LOOKS_UP_DEG:
        return (f"{label} looks {-np.degrees(pitch):.0f} degrees up from {height_m:.2f} m: is its pitch's sign right "
                "(positive looks down)? People are filmed from above or level",)
    return ()
