"""``ray3d live --config FILE``: a whole deployment in one YAML (or JSON) file. Its keys are ``ray3d live``'s
flags without their dashes (``stall-timeout: 5``, ``no-page: true``), and ``cameras``, one entry per stream: its
``source``, its ``camera`` file and, where its clock is not in step with the first's, its ``offset`` in seconds. Paths
in it are relative to the file's folder. It is checked against the published JSON Schema
(``assets/live-config.schema.json``, made from the flags themselves: ``python -m ray3d.cli.live_config``), each
mistake one line naming its key; a flag given on the command line wins over the file."""

from __future__ import annotations

import argparse
import datetime
import difflib
import json
from pathlib import Path

from ray3d.errors import InputError
from ray3d.io.text_files import read_json_or_yaml

SCHEMA_PATH = Path(__file__).resolve().parent.parent / "assets" / "live-config.schema.json"
SCHEMA_ID = "https://github.com/ray3d/ray3d/live-config.schema.json"
# Flags the file says otherwise: the file itself, and the cameras (``cameras``: a stream, its camera file and its
# clock's offset together, rather than three lists to keep in order).
NOT_KEYS = {"help", "config", "source", "camera", "offsets"}
# Keys whose values are paths, read relative to the file's folder; and those that name a shipped thing or a path.
PATH_KEYS = {"out", "site", "store"}
NAME_OR_PATH_KEYS = {"checkpoint", "floor"}
CAMERA_ENTRY = {
    "type": "object", "additionalProperties": False, "required": ["source"],
    "properties": {
        "source": {"type": ["string", "integer"], "description": "a video file, a camera device number or a stream "
                                                                 "URL OpenCV opens (rtsp://, http://)"},
        "camera": {"type": "string", "description": "its calibration: camera JSON (ours or OpenCV), OpenCV YAML, "
                                                    "FILE.toml:NAME (Pose2Sim, Anipose)"},
        "offset": {"type": "number", "description": "seconds its clock is ahead of the first camera's (default 0)"}}}


def key_of(action: argparse.Action) -> str:
    """A flag's key in the file: its long name without the dashes."""
    return action.option_strings[-1].lstrip("-")


def _keyed(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    # argparse lists a parser's flags only in its ``_actions``.
    return {key_of(a): a for a in parser._actions if a.option_strings and a.dest not in NOT_KEYS}


def config_schema(parser: argparse.ArgumentParser) -> dict:
    """The JSON Schema of a deployment file for ``ray3d live``'s ``parser``: one property per flag, typed as the
    flag reads its value, described by its help."""
    properties = {"cameras": {"type": "array", "minItems": 1, "items": CAMERA_ENTRY,
                              "description": "one entry per stream, each a calibrated camera of one site"}}
    for key, action in _keyed(parser).items():
        if isinstance(action, argparse._StoreTrueAction):
            kind = {"type": "boolean"}
        elif action.choices:
            kind = {"enum": list(action.choices)}
        else:
            kind = {"type": {float: "number", int: "integer"}.get(action.type, "string")}
        properties[key] = {**kind, "description": (action.help or "").replace("%%", "%")}
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
            "title": "a ray3d live deployment", "type": "object", "additionalProperties": False,
            "required": ["cameras"], "properties": properties}


def _plain(value):
    """YAML's dates and times as the ISO 8601 text the flags read."""
    if isinstance(value, (datetime.date, datetime.datetime)):
        return value.isoformat()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _where(path) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".") or "the file"


def _mistakes(document, schema: dict) -> list[str]:
    """Each way ``document`` breaks ``schema``, one line naming the key (an unknown key with the one it probably
    meant)."""
    try:
        from jsonschema import Draft202012Validator
    except ImportError:
        raise InputError("a deployment file is checked by jsonschema: pip install 'ray3d[live]'", ("config",)) from None

    lines = []
    for error in Draft202012Validator(schema).iter_errors(document):
        if error.validator == "additionalProperties":
            known = list(error.schema.get("properties", {}))
            for key in sorted(set(error.instance) - set(known)):
                close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
                lines.append(f"{_where([*error.path, key])}: not a key here" +
                             (f"; did you mean {close[0]}?" if close else f" (the keys: {', '.join(known)})"))
        elif error.validator == "required":
            lines.append(f"{_where(error.path)}: {error.message.split(' ')[0].strip(chr(39))} missing")
        else:
            lines.append(f"{_where(error.path)}: {error.message}")
    return sorted(lines)


def _beside(folder: Path, text: str) -> str:
    """A path in the file, relative to its folder; a URL, a device number or a named camera set as it is."""
    if "://" in text or text.isdigit() or text.startswith("h36m:") or Path(text).is_absolute():
        return text
    return str(folder / text)


def read_live_config(path: str | Path, parser: argparse.ArgumentParser) -> dict:
    """The values of ``ray3d live``'s flags (by their ``dest``) a deployment file gives, checked against
    ``config_schema(parser)``; ``InputError`` with one line per mistake."""
    path = Path(path)
    document = _plain(read_json_or_yaml(path))
    if not isinstance(document, dict):
        raise InputError(f"{path}: expected keys and values (the flags' names, and cameras), got "
                         f"{type(document).__name__}", ("config",))
    mistakes = _mistakes(document, config_schema(parser))
    if mistakes:
        raise InputError("\n".join(f"{path}: {line}" for line in mistakes), ("config",))
    folder, values, flags = path.parent, {}, _keyed(parser)
    for key, value in document.items():
        if key == "cameras":
            continue
        if key in PATH_KEYS or key in NAME_OR_PATH_KEYS and (folder / str(value)).exists():
            value = _beside(folder, str(value))
        action = flags[key]
        try:
            values[action.dest] = action.type(str(value)) if action.type and not isinstance(value, bool) else value
        except (ValueError, TypeError, argparse.ArgumentTypeError) as err:
            raise InputError(f"{path}: {key}: {err}", ("config",)) from None
    cameras = document["cameras"]
    values["source"] = [_beside(folder, str(c["source"])) for c in cameras]
    files = [c.get("camera") for c in cameras]
    if any(files):
        if not all(files):
            missing = next(k for k, f in enumerate(files) if not f)
            raise InputError(f"{path}: cameras[{missing}]: camera missing (give each camera its file, or none)",
                             ("config",))
        values["camera"] = [_beside(folder, f) for f in files]
    if any("offset" in c for c in cameras):
        values["offsets"] = ",".join(f"{float(c.get('offset', 0.0)):g}" for c in cameras)
    return values


def with_config(parser: argparse.ArgumentParser, live_parser: argparse.ArgumentParser, argv: list[str] | None,
                path: str | Path) -> argparse.Namespace:
    """``argv`` parsed again with the deployment file at ``path`` giving ``ray3d live``'s defaults: what the
    command line gives wins."""
    values = read_live_config(path, live_parser)
    live_parser.set_defaults(**values)
    args = parser.parse_args(argv)
    if "camera" in values and args.camera is not values["camera"]:
        args.camera = args.camera[len(values["camera"]):]  # argparse appends the command line's to the default's
    return args


def main() -> None:
    """Writes the published schema (``SCHEMA_PATH``) from the flags as they are."""
    from ray3d.cli.parser import build_parser, subcommand_parser

    SCHEMA_PATH.write_text(json.dumps(config_schema(subcommand_parser(build_parser(), "live")), indent=1) + "\n")
    print(f"wrote {SCHEMA_PATH}")


if __name__ == "__main__":
    main()
