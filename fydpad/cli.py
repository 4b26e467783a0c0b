"""The ``fydpad`` command: one subcommand per module in :mod:`fydpad.commands`."""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence

from fydpad import __version__
from fydpad.errors import FydpadError, one_line_warnings
from vision.recording import PadRecording

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS = (
    "demo", "track", "run", "replay", "synth", "calibrate", "softness", "texture", "experiment",
    "chain", "config", "export",
)


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


def build_parser() -> argparse.ArgumentParser:
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
    for name in COMMANDS:
        importlib.import_module(f"fydpad.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
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
