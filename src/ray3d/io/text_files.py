"""Reading the JSON and CSV files the user gave us: errors name the file and say what is wrong."""

from __future__ import annotations

import contextlib
import csv
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ray3d.errors import InputError


def read_text(path: str | Path) -> str:
    """A user's text file's contents; a file that cannot be read, or is not text, refused in one line."""
    with _refused(path):
        return Path(path).read_text()


def read_json(path: str | Path) -> Any:
    text = read_text(path)
    with _refused(path):
        return json.loads(text)


@contextlib.contextmanager
def _refused(path: str | Path) -> Iterator[None]:
    """What reading ``path`` as text or JSON raises, turned into its one-line refusal."""
    try:
        yield
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file") from None
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None
    except json.JSONDecodeError as err:
        raise InputError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None
    except RecursionError:
        raise InputError(f"{path}: JSON nested too deeply for any file ray3d reads") from None


def read_json_or_yaml(path: str | Path) -> Any:
    """A file's contents: YAML for .yaml / .yml (parsed safely: plain data only), else JSON."""
    path = Path(path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        return read_json(path)
    import yaml

    text = read_text(path)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise InputError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None


def read_csv_rows(path: str | Path) -> list[dict[str, str]]:
    """The rows of a CSV file with a header row, each {column: text} (a UTF-8 byte-order mark is ignored)."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            return list(csv.DictReader(handle))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise InputError(f"{path}: cannot read as CSV ({err})") from None
