"""The command line as data (``cli/flags.toml``): every table and command in it used, every flag's keywords ones
argparse takes, the flags added in the file's order and with the values the code names."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from ray3d.cli import arguments
from ray3d.cli.parser import build_parser, handlers


def _flag_tables(node: dict, name: str = ""):
    """The dotted names of flags.toml's tables of flags: tables whose values are all one flag's keywords."""
    for key, value in node.items():
        dotted = f"{name}.{key}" if name else key
        if all(isinstance(spec, dict) and not any(isinstance(v, dict) for v in spec.values())
               for spec in value.values()):
            yield dotted
        else:
            yield from _flag_tables(value, dotted)


def _commands(handlers: dict, group: str = ""):
    for name, handler in handlers.items():
        dotted = f"{group}.{name}" if group else name
        yield dotted
        if isinstance(handler, dict):
            yield from _commands(handler, name)


def _parsers(parser: argparse.ArgumentParser, path: tuple = ()):
    """(the command's words, its parser) for every command with flags of ``build_parser()``."""
    groups = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for action in groups:
        for name, child in action.choices.items():
            yield from _parsers(child, (*path, name))
    if path and not groups:
        yield path, parser


def test_every_table_and_command_of_the_file_is_used(monkeypatch):
    read, table = [], arguments.flag_table

    def recorded(name: str) -> dict:
        read.append(name)
        return table(name)

    monkeypatch.setattr(arguments, "flag_table", recorded)
    build_parser()
    file = {k: v for k, v in arguments.flag_file().items() if k != "commands"}
    assert set(_flag_tables(file)) == set(read)
    assert list(arguments.flag_file()["commands"]) == list(_commands(handlers()))


def test_every_flag_keyword_and_type_in_the_file_is_argparse_s():
    def specs(node: dict):
        for key, value in node.items():
            if key.startswith(arguments.SHARED):
                continue  # an inclusion: its words
            if any(isinstance(v, dict) for v in value.values()):
                yield from specs(value)
            else:
                yield key, value

    file = {k: v for k, v in arguments.flag_file().items() if k != "commands"}
    found = list(specs(file))
    assert len(found) > 150
    for flag, spec in found:
        assert set(spec) <= arguments.KEYWORDS, flag
        assert spec.get("type", "int") in arguments.CONVERTERS, flag
        assert spec.get("action", "store_true") in ("store_true", "append"), flag


def test_a_mistake_in_the_file_is_refused_when_the_parser_is_built():
    with pytest.raises(ValueError, match="defualt: not an argparse keyword"):
        arguments.flag_keywords({"defualt": 3}, {})
    with pytest.raises(ValueError, match="type integer: not one of int, float"):
        arguments.flag_keywords({"type": "integer"}, {})
    with pytest.raises(ValueError, match="NOT_A_CONSTANT: not a named value"):
        arguments.flag_keywords({"help": "see {NOT_A_CONSTANT} in {json,md}"}, {})


def test_placeholders_are_the_values_the_code_names():
    names = {"SETS": ("a", "b"), "HEIGHT": 1.7, "role": "with --pitch"}
    assert arguments.flag_keywords({"choices": "{SETS}", "default": "{HEIGHT}", "type": "float",
                                    "help": "{role}: {HEIGHT:.2f} m, in {json,md} (4 %%)"}, names) == {
        "choices": ("a", "b"), "default": 1.7, "type": float, "help": "with --pitch: 1.70 m, in {json,md} (4 %%)"}
    assert arguments.flag_keywords({"type": "path", "default": "ray3d-demo"}, {})["default"] == Path("ray3d-demo")


def test_each_command_has_its_table_s_flags_in_the_file_s_order():
    parsers = dict(_parsers(build_parser()))
    flags = [a.option_strings[-1] if a.option_strings else a.dest for a in parsers[("bench", "level")]._actions]
    assert flags == ["--help", *list(arguments.flag_table("bench.level"))[:-1], "--data-dir"]
    video = [a.option_strings[-1] if a.option_strings else a.dest for a in parsers[("video",)]._actions]
    assert video[:3] == ["--help", "input", "--camera"] and video[-2:] == ["--frame", "--force"]


def test_the_values_the_code_names_reach_the_parser():
    from ray3d.body import ADULT_STATURE_M
    from ray3d.models.precision import PRECISIONS
    from ray3d.video.detectors import DEFAULT_DETECTOR

    parser = build_parser()
    args = parser.parse_args(["calibrate", "--out", "c.json"])
    assert args.person_height == ADULT_STATURE_M
    assert parser.parse_args(["bench", "real-near", "--out", "o"]).data == Path("../shared/data/real-near")
    assert parser.parse_args(["video", "v.mp4", "--out", "o"]).detector == DEFAULT_DETECTOR
    precision = {a.dest: a for a in dict(_parsers(parser))[("evaluate",)]._actions}["precision"]
    assert precision.choices == PRECISIONS
    level = dict(_parsers(parser))[("bench", "level")].format_help()
    assert "4 % taller" in " ".join(level.split())


def test_every_flag_a_user_of_the_site_commands_gives_says_what_it_does():
    """The commands outside the developers' (data, train, bench)."""
    for path, parser in _parsers(build_parser()):
        if path[0] in ("data", "train", "bench"):
            continue
        assert not [a.dest for a in parser._actions if not a.help], path
