"""``fydpad --help`` imports no command module, and each ``fydpad COMMAND --help`` loads
none of the heavy libraries (its command imports them when it runs). How long they take
is benchmarks/bench_help.py's; this checks what they load, in a fresh interpreter."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fydpad import cli

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("scipy.signal", "pybullet", "aiohttp", "matplotlib")

PROBE = """
import json, sys
from fydpad.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)), file=sys.stderr)
"""


def loaded(*argv: str) -> set[str]:
    r = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True,
                       cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
                       timeout=120)
    return set(json.loads(r.stderr.strip().splitlines()[-1]))


def test_top_level_help_imports_no_command():
    mods = loaded("--help")
    assert not {m for m in mods if m.startswith("fydpad.commands.")}
    assert not {m for m in mods if m.split(".")[0] in ("cv2", "numpy", *HEAVY)}


@pytest.mark.parametrize("command", sorted(cli.COMMANDS))
def test_command_help_loads_no_heavy_library(command):
    mods = loaded(command, "--help")
    assert f"fydpad.commands.{command}" in mods
    assert not {m for m in mods for h in HEAVY if m == h or m.startswith(h + ".")}


def test_the_one_help_lines_are_the_commands_own():
    parser = cli.build_parser()  # every module registered
    sub = next(a for a in parser._actions if a.dest == "command")
    own = {a.dest: a.help for a in sub._choices_actions}
    assert own == cli.COMMANDS


def test_texture_lists_the_families_there_are():
    from fydpad.commands import texture
    from fydpad.texture import families

    assert texture.KIND_NAMES == families.KIND_NAMES
    assert texture.FIT_KIND_NAMES == families.FIT_KIND_NAMES


def test_synth_lists_the_trajectories_effects_and_videos_there_are():
    from fydpad import synth
    from fydpad.commands import synth as command
    from vision import recording

    assert command.TRAJECTORIES == synth.TRAJECTORIES
    assert command.EFFECT_HELP == synth.EFFECT_HELP
    assert command.IMAGE_FLIPS == recording.IMAGE_FLIPS
    assert command.VIDEO_NAMES == recording.VIDEO_NAMES


def test_softness_names_the_specimens_there_are():
    from fydpad.commands.softness import SPECIMEN_STIFFNESSES
    from fydpad.softness import SPECIMENS

    assert SPECIMEN_STIFFNESSES == ", ".join(
        f"{k} {v.lambda_n_per_mm} N/mm" for k, v in SPECIMENS.items())


def test_track_lists_the_trackers_there_are():
    from fydpad.commands.track import TRACKER_METHODS
    from vision.contact import METHODS

    assert TRACKER_METHODS == METHODS


def test_the_chosen_command_is_found_after_a_global_config():
    assert cli.chosen_command(["--config", "track", "run", "--help"]) == "run"
    assert cli.chosen_command(["--help"]) is None
    assert cli.chosen_command(["track", "rec"]) == "track"
