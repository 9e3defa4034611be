"""The console script: --version, --help and the main job."""

from __future__ import annotations

import subprocess
import sys

import ray3d
from ray3d.cli import main


def test_version_and_help(capsys):
    for argv in (["--version"], ["--help"]):
        try:
            main(argv)
        except SystemExit as exit_:
            assert exit_.code == 0
    out = capsys.readouterr().out
    assert f"ray3d {ray3d.__version__}" in out and "demo" in out


def test_console_script_runs_the_demo():
    result = subprocess.run([sys.executable, "-m", "ray3d.cli", "demo"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("h36m:S") == 28
    worst = float(result.stdout.strip().splitlines()[-1].split(":")[-1].split()[0])
    assert worst < 1e-6
