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
#: Commands whose --help still loads a heavy library at registration (their modules are
#: the texture helpers' and the synthetic pad's: their option lists come from it).
NOT_YET_FAST = {"texture", "synth"}

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


@pytest.mark.parametrize("command", sorted(set(cli.COMMANDS) - NOT_YET_FAST))
def test_command_help_loads_no_heavy_library(command):
    mods = loaded(command, "--help")
    assert f"fydpad.commands.{command}" in mods
    assert not {m for m in mods for h in HEAVY if m == h or m.startswith(h + ".")}


def test_the_one_help_lines_are_the_commands_own():
    parser = cli.build_parser()  # every module registered
    sub = next(a for a in parser._actions if a.dest == "command")
    own = {a.dest: a.help for a in sub._choices_actions}
    assert own == cli.COMMANDS


def test_run_lists_the_texture_methods_there_are():
    from fydpad.commands.run import TEXTURE_METHODS
    from fydpad.texture.lpc.interpolation import METHODS

    assert TEXTURE_METHODS == METHODS


def test_track_lists_the_trackers_there_are():
    from fydpad.commands.track import TRACKER_METHODS
    from vision.contact import METHODS

    assert TRACKER_METHODS == METHODS


def test_the_chosen_command_is_found_after_a_global_config():
    assert cli.chosen_command(["--config", "track", "run", "--help"]) == "run"
    assert cli.chosen_command(["--help"]) is None
    assert cli.chosen_command(["track", "rec"]) == "track"
