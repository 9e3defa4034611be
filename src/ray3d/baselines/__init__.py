"""Baselines that need no learning."""
