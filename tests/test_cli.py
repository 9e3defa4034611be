"""The console script: --version and --help."""

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
    assert f"ray3d {ray3d.__version__}" in out
    for command in ("demo", "data", "train", "evaluate", "lift", "export", "models"):
        assert command in out


def test_console_script_entry_point():
    result = subprocess.run([sys.executable, "-m", "ray3d.cli", "--version"], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == f"ray3d {ray3d.__version__}"
