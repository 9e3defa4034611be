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


def _help(command: str, capsys) -> dict[str, str]:
    """``ray3d COMMAND --help``: {flag: its help text, on one line}."""
    import re

    try:
        main([command, "--help"])
    except SystemExit as exit_:
        assert exit_.code == 0
    flags, flag = {}, None
    for line in capsys.readouterr().out.splitlines():
        start = re.match(r"^  (--[a-z0-9-]+)", line)
        if start:
            flag = start.group(1)
            flags[flag] = line[start.end():]
        elif flag and line.startswith("      "):
            flags[flag] += line
    return {name: " ".join(text.split()) for name, text in flags.items()}


def test_live_help_says_how_live_smooths_what_it_answers_and_what_smooth_3d_smooths(capsys):
    """``ray3d live`` smooths its answers as they happen by One-Euro (``LIVE_SMOOTHING``), whatever --smooth-3d
    says; --smooth-3d (default ``OUTPUT_SMOOTHING``), --smooth-2d, --flip-test and --no-refine shape only
    world.csv, each person lifted again as they leave; live writes the world frame only."""
    from ray3d.live.people import LIVE_SMOOTHING
    from ray3d.temporal import OUTPUT_SMOOTHING, OneEuro

    min_cutoff, beta = LIVE_SMOOTHING
    assert OneEuro(*LIVE_SMOOTHING).min_cutoff == min_cutoff and OneEuro(*LIVE_SMOOTHING).beta == beta
    live = _help("live", capsys)
    smooth_3d = live["--smooth-3d"]
    assert f"world.csv's joints in time, each person lifted again as they leave (default {OUTPUT_SMOOTHING})" \
        in smooth_3d
    assert f"always smoothed causally, by a One-Euro filter ({min_cutoff:g} Hz at rest, its cutoff {beta:g} Hz " \
        "higher per m/s)" in smooth_3d
    for flag in ("--smooth-2d", "--flip-test", "--no-refine"):
        assert "world.csv only" in live[flag], flag
    assert "camera" not in live["--frame"]
    offline = _help("video", capsys)  # elsewhere the flags shape every output, as before
    assert offline["--smooth-3d"].endswith(f"smooth the 3D output in time (default {OUTPUT_SMOOTHING})")
    assert "world.csv" not in offline["--smooth-2d"] and "camera" in offline["--frame"]

def test_console_script_entry_point():
    result = subprocess.run([sys.executable, "-m", "ray3d.cli", "--version"], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == f"ray3d {ray3d.__version__}"


def test_library_errors_name_arguments_and_the_cli_names_its_flags(tmp_path, capsys):
    from ray3d import InputError
    from ray3d.io.atomic import atomic_path

    taken = tmp_path / "taken.json"
    taken.write_text("{}")
    try:
        with atomic_path(taken):
            pass
    except InputError as err:
        assert "--" not in str(err) and "(argument: overwrite)" in str(err)
    assert main(["export", "--checkpoint", "ray3d", "--out", str(taken.with_suffix(".safetensors"))]) == 0
    assert main(["export", "--checkpoint", "ray3d", "--out", str(taken.with_suffix(".safetensors"))]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refusing to overwrite it (--force)" in err and "argument" not in err


def test_cli_handlers_are_thin():
    """The CLI's own files hold parsing, printing and exit codes: together well under the library's size."""
    from pathlib import Path

    import ray3d.cli as cli

    lines = {p.name: len(p.read_text().splitlines()) for p in Path(cli.__file__).parent.glob("*.py")}
    assert all(n < 400 for n in lines.values()), lines
