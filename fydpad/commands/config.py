"""``fydpad config``: show the effective configuration."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse

from fydpad.cli import add_config_argument


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "config",
        help="show the effective device configuration",
        description=(
            "Show the device configuration in effect: the paper's defaults overridden by "
            "--config FILE. The output is valid TOML: save it, edit it, pass it back."
        ),
    )
    p.add_argument("action", choices=["show"], help="'show': print the configuration as TOML")
    add_config_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fydpad.config import config_to_toml, load_config

    print(config_to_toml(load_config(args.config)), end="")
    return 0
