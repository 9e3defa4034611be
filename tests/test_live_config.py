"""``ray3d live --config``: a deployment in one file, the same run as its flags, checked against the published
schema with one line per mistake, the command line winning."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from ray3d import InputError
from ray3d.cli import main
from ray3d.cli.live_config import SCHEMA_PATH, config_schema, read_live_config, with_config
from ray3d.cli.parser import build_parser, subcommand_parser

DOCS = Path(__file__).resolve().parent.parent / "docs" / "live.md"


def _parsed(argv: list[str]):
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.config is not None:
        args = with_config(parser, subcommand_parser(parser, "live"), argv, args.config)
    return {k: v for k, v in vars(args).items() if k not in ("config", "handler", "until")}


def test_the_published_schema_is_the_one_the_flags_make():
    published = json.loads(SCHEMA_PATH.read_text())
    assert published == config_schema(subcommand_parser(build_parser(), "live")), \
        "a flag changed: write the schema again with python -m ray3d.cli.live_config"
    assert {"cameras", "site", "store", "mqtt", "port", "no-page", "stall-timeout"} <= set(published["properties"])
    assert published["properties"]["port"]["type"] == "integer"
    assert published["properties"]["precision"]["enum"] == ["fp32", "bf16", "int8"]


def test_the_deployment_in_the_docs_is_the_run_its_flags_ask_for(tmp_path):
    example = re.search(r"<!-- deployment example.*?-->\n```yaml\n(.*?)```", DOCS.read_text(), re.S).group(1)
    config = tmp_path / "shop.yaml"
    config.write_text(example)
    flags = ["live", "rtsp://cam1.local/stream", "rtsp://cam2.local/stream", "--camera", str(tmp_path / "cam1.json"),
             "--camera", str(tmp_path / "cam2.json"), "--offsets", "0,0.2", "--site", str(tmp_path / "shop-site.yaml"),
             "--out", "/var/lib/ray3d/shop", "--store", "postgresql://ray3d@db.local/shop", "--mqtt",
             "mqtt://127.0.0.1/shop", "--every", "1h", "--host", "127.0.0.1", "--port", "8765", "--quiet",
             "--reconnect-max", "60", "--stall-timeout", "10"]
    assert _parsed(["live", "--config", str(config)]) == _parsed(flags)


def test_a_flag_on_the_command_line_wins_over_the_file(tmp_path):
    config = tmp_path / "site.yaml"
    config.write_text("cameras:\n  - {source: a.mp4, camera: a.json}\nport: 9000\nquiet: true\nout: out\n")
    given = _parsed(["live", "--config", str(config), "--port", "9100", "--camera", "/elsewhere/b.json"])
    assert given["port"] == 9100 and given["camera"] == ["/elsewhere/b.json"] and given["quiet"] is True
    assert given["source"] == [str(tmp_path / "a.mp4")] and given["out"] == tmp_path / "out"  # beside the file
    kept = _parsed(["live", "--config", str(config)])
    assert kept["port"] == 9000 and kept["camera"] == [str(tmp_path / "a.json")]
    assert _parsed(["live", "--config", str(config), "other.mp4"])["source"] == ["other.mp4"]


def test_every_mistake_in_a_deployment_file_is_one_line_naming_its_key(tmp_path):
    config = tmp_path / "shop.yaml"
    config.write_text("cameras:\n  - source: a.mp4\n    camra: a.json\n  - camera: b.json\n"
                      "stall-timout: 5\nport: eighty\nprecision: fp64\n")
    with pytest.raises(InputError) as caught:
        read_live_config(config, subcommand_parser(build_parser(), "live"))
    lines = caught.value.message.splitlines()
    assert lines == [f"{config}: cameras[0].camra: not a key here; did you mean camera?",
                     f"{config}: cameras[1]: source missing",
                     f"{config}: port: 'eighty' is not of type 'integer'",
                     f"{config}: precision: 'fp64' is not one of ['fp32', 'bf16', 'int8']",
                     f"{config}: stall-timout: not a key here; did you mean stall-timeout?"]


@pytest.mark.parametrize("text, says", [
    ("cameras: []\n", "cameras: [] should be non-empty"),
    ("port: 8765\n", "the file: cameras missing"),
    ("- a\n- b\n", "expected keys and values"),
    ("cameras: [{source: a.mp4}]\nuntil: soon\n", "until: 'soon' is neither a duration"),
    ("cameras: [{source: a.mp4, camera: a.json}, {source: b.mp4}]\n", "cameras[1]: camera missing"),
    ("cameras: [{source: a.mp4\n", "not valid YAML"),
])
def test_a_bad_deployment_file_is_refused_in_the_cli_with_exit_2(tmp_path, capsys, text, says):
    config = tmp_path / "shop.yaml"
    config.write_text(text)
    assert main(["live", "--config", str(config)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("ray3d live: error: ") and says in error and "Traceback" not in error


def test_without_a_stream_or_an_out_folder_live_says_which_is_missing(tmp_path, capsys):
    assert main(["live", "--out", str(tmp_path)]) == 2
    assert "give a stream" in capsys.readouterr().err
    config = tmp_path / "shop.yaml"
    config.write_text("cameras: [{source: a.mp4}]\n")
    assert main(["live", "--config", str(config)]) == 2
    assert "give the folder for the outputs (out) (--out)" in capsys.readouterr().err
