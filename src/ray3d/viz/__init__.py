"""Visualisation: 2D + 3D animations (GIF, MP4), a self-contained HTML viewer, metric plots."""
