"""The ``fydpad`` command: one subcommand per module in :mod:`fydpad.commands`."""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence

from fydpad import __version__
from fydpad.errors import FydpadError, one_line_warnings

#: Subcommand modules, in the order ``--help`` lists them, with the one line it shows for
#: each: ``fydpad --help`` imports none of them, ``fydpad COMMAND`` only its own
#: (tests/cli/test_fast_help.py checks these lines against each module's own).
COMMANDS = {
    "demo": "the whole chain on the bundled recordings with the simulated robot",
    "track": "track the finger's contact in a recording or a live camera",
    "run": "run the master station (live camera or a replayed recording)",
    "replay": "stream a recording's finger track to a slave robot and report the error",
    "synth": "write a synthetic pad session recording with ground truth",
    "calibrate": "calibrate the IR sensors, the load cell, the camera or the workspace",
    "softness": "characterise the fabric's stiffness table and specimens",
    "texture": "texture models: fit from scans, synthesize, evaluate, identify",
    "experiment": "the absolute identification experiment: report the results",
    "chain": "identify the actuator chain's transfer function, check compensation",
    "config": "show the effective device configuration",
    "export": "export a recording into other tools' formats (a ROS 2 bag)",
}
ALL = "*"


def add_config_argument(parser: argparse.ArgumentParser) -> None:
    """``--config FILE`` on a subcommand; it may also be given before the subcommand."""
    parser.add_argument(
        "--config", metavar="FILE", default=argparse.SUPPRESS,
        help="device configuration (TOML) overriding the paper's defaults",
    )


def add_truncation_argument(parser: argparse.ArgumentParser) -> None:
    """``--allow-truncated`` on a command that reads recordings."""
    parser.add_argument(
        "--allow-truncated", action="store_true", default=argparse.SUPPRESS,
        help="a recording's video that ends before its frames.csv, ir.csv, force.csv or "
        "truth.csv (truncated, or a frame that does not decode) is an error naming the file "
        "and the last good frame; with this option, a warning, and the frames before it "
        "are used",
    )


def chosen_command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names (None: none, e.g. ``fydpad --help``)."""
    args = iter(argv)
    for arg in args:
        if arg == "--config":
            next(args, None)
        elif arg in COMMANDS:
            return arg
        elif not arg.startswith("-"):
            return None
    return None


def build_parser(only: str | None = ALL) -> argparse.ArgumentParser:
    """The parser; ``only``: the one subcommand whose module is imported and registered
    (the others get their one help line), ``ALL`` for every one, None for none."""
    parser = argparse.ArgumentParser(
        prog="fydpad",
        description=(
            "Master station software for the FYD-pad fabric tactile display: track the finger "
            "on the fabric, render softness and texture, drive a slave robot."
        ),
        epilog="Run 'fydpad COMMAND --help' for the options of one command.",
    )
    parser.add_argument("--version", action="version", version=f"fydpad {__version__}")
    parser.add_argument(
        "--config", metavar="FILE", default=None,
        help="device configuration (TOML) overriding the paper's defaults",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, help_text in COMMANDS.items():
        if only in (ALL, name):
            importlib.import_module(f"fydpad.commands.{name}").register(sub)
        else:
            sub.add_parser(name, help=help_text, add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(only=chosen_command(argv))
    args = parser.parse_args(argv)
    from vision.recording import PadRecording  # OpenCV: not for --help, which exits above

    shown = warnings.formatwarning
    one_line_warnings(f"fydpad {args.command}")
    PadRecording.allow_truncated = bool(getattr(args, "allow_truncated", False))
    try:
        return int(args.func(args) or 0)
    except FydpadError as exc:  # bad input or a device fault: one line, no traceback
        print(f"fydpad {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"fydpad {args.command}: interrupted", file=sys.stderr)
        return 130
    finally:
        warnings.formatwarning = shown  # a caller's own format (main called in-process)
        PadRecording.allow_truncated = False


if __name__ == "__main__":
    sys.exit(main())
