"""The one TOML configuration: paper defaults, overrides, and errors naming file and key."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from fydpad.cli import main
from fydpad.config import ConfigError, config_to_toml, load_config


def test_defaults_are_the_papers_values():
    c = load_config(None)
    assert c.tracker.threshold == 150 and c.tracker.beta == 5.0
    assert c.tracker.processing_size == (160, 120)
    assert c.camera.workspace_mm == (100.0, 70.0)
    assert c.camera.frame_size == (640, 480) and c.camera.fps == 30.0
    assert c.loops.render_hz == 1000.0


def test_show_round_trips(tmp_path: Path, capsys):
    assert main(["config", "show"]) == 0
    text = capsys.readouterr().out
    p = tmp_path / "c.toml"
    p.write_text(text)
    assert load_config(p) == load_config(None)


def test_override_and_global_flag(tmp_path: Path, capsys):
    p = tmp_path / "c.toml"
    p.write_text('[tracker]\nthreshold = 120\n[camera]\nimage_flip = "none"\n')
    assert main(["--config", str(p), "config", "show"]) == 0
    data = tomllib.loads(capsys.readouterr().out)
    assert data["tracker"]["threshold"] == 120 and data["tracker"]["beta"] == 5.0
    assert data["camera"]["image_flip"] == "none"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[tracker]\nthreshhold = 3\n", "unknown key 'tracker.threshhold'"),
        ("[nonsense]\na = 1\n", "unknown key 'nonsense'"),
        ('[tracker]\nthreshold = "high"\n', "tracker.threshold: expected an integer"),
        ("[tracker]\nbeta = true\n", "tracker.beta: expected a number"),
        ("[camera]\nroi_px = [1, 2, 3]\n", "camera.roi_px: expected an array of 4 values"),
        ('[camera]\nimage_flip = "sideways"\n', "camera: image_flip must be one of"),
        ("[tracker\n", "not valid TOML"),
    ],
)
def test_errors_name_file_and_key(tmp_path: Path, text, message):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(p)
    assert str(p) in str(err.value) and message in str(err.value)


def test_bad_config_on_the_command_line_is_one_line(tmp_path: Path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text("[tracker]\nthreshold = 1.5\n")
    assert main(["config", "show", "--config", str(p)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tracker.threshold" in err[0]


def test_missing_file(tmp_path: Path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "none.toml")


def test_to_toml_is_valid_toml():
    assert tomllib.loads(config_to_toml(load_config(None)))["loops"]["vision_hz"] == 30.0
