"""docs/calibration_files.md's walkthroughs, run as written: each ```bash block of its
"Walkthroughs" section, command by command, in an empty folder (``fydpad`` is this
checkout's CLI, called in-process); every command exits 0, every file a command names
with --out or --plot is written, and the output the page quotes is the output printed.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from fydpad.cli import main

PAGE = Path(__file__).resolve().parents[2] / "docs" / "calibration_files.md"


def walkthroughs() -> dict[str, tuple[list[str], list[str]]]:
    """Heading -> (the bash block's commands, the lines of the plain block quoting their
    output, if any)."""
    text = PAGE.read_text(encoding="utf-8")
    section = text.split("## Walkthroughs on sample inputs", 1)[1]
    out = {}
    for part in re.split(r"\n### ", section)[1:]:
        title = part.splitlines()[0].strip()
        bash = re.findall(r"```bash\n(.*?)```", part, re.S)
        quoted = re.findall(r"```\n(.*?)```", re.sub(r"```bash\n.*?```", "", part, flags=re.S),
                            re.S)
        assert len(bash) == 1, f"{PAGE.name} '{title}': expected one bash block"
        commands = [ln.strip() for ln in bash[0].splitlines() if ln.strip()]
        out[title] = (commands, quoted[0].strip().splitlines() if quoted else [])
    return out


WALKTHROUGHS = walkthroughs()
SLOW = {"Indentation and workspace mapping"}  # renders a 30 s video of the synthetic pad


def run_walkthrough(title: str, tmp_path, monkeypatch, capsys) -> None:
    commands, quoted = WALKTHROUGHS[title]
    monkeypatch.chdir(tmp_path)
    printed = []
    for command in commands:
        argv = shlex.split(command)
        assert argv[0] == "fydpad", command
        assert main(argv[1:]) == 0, f"{command}: {capsys.readouterr().err}"
        printed += capsys.readouterr().out.splitlines()
        for flag in ("--out", "--plot"):
            if flag in argv:
                written = tmp_path / argv[argv.index(flag) + 1]
                assert written.exists() and written.stat().st_size > 0, command
    for line in quoted:
        assert line in printed, f"{title}: the page quotes {line!r}; printed:\n" + "\n".join(
            printed)


def test_every_calibration_command_has_a_walkthrough():
    commands = " ".join(c for cs, _ in WALKTHROUGHS.values() for c in cs)
    for name in ("calibrate ir", "calibrate force", "calibrate camera",
                 "calibrate indentation", "calibrate workspace", "softness calibrate",
                 "softness fit-specimen"):
        assert f"fydpad {name} " in commands, name


@pytest.mark.parametrize("title", [t for t in WALKTHROUGHS if t not in SLOW])
def test_walkthrough(title, tmp_path, monkeypatch, capsys):
    run_walkthrough(title, tmp_path, monkeypatch, capsys)


@pytest.mark.slow
@pytest.mark.parametrize("title", sorted(SLOW))
def test_slow_walkthrough(title, tmp_path, monkeypatch, capsys):
    run_walkthrough(title, tmp_path, monkeypatch, capsys)
