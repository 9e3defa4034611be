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
