"""Command-line options shared by the texture benchmarks that score held-out strokes
(``texture_targets.py``, ``texture_speed_bias.py``; run as ``python benchmarks/NAME.py``)."""

from __future__ import annotations

import argparse
import math

from fydpad.texture.scan_generator import TEXTURES


def add_stroke_options(ap: argparse.ArgumentParser, held: int, held_help: str) -> None:
    """--textures, --speeds, --train-seed, --held (``held`` strokes by default) and
    --load-scale (``generate_scan``'s ``load_scale``)."""
    ap.add_argument("--textures", default="all", help="comma-separated, or all")
    ap.add_argument("--speeds", default="10,15,20,25,30,35,40", help="mm/s, comma-separated")
    ap.add_argument("--train-seed", type=int, default=1)
    ap.add_argument("--held", type=int, default=held, help=held_help)
    ap.add_argument("--load-scale", type=float, default=1.0, metavar="S",
                    help="the hand's mean load over each texture's own, for training and "
                         "held-out strokes alike (0.3: a light touch, where the tip "
                         "loses contact on brick and the sandpapers; default 1)")


def textures_and_speeds(ap: argparse.ArgumentParser, args: argparse.Namespace
                        ) -> tuple[list[str], list[float]]:
    """The generator's textures and the speeds (mm/s) the options name; an unknown
    texture is refused with the known ones."""
    names = list(TEXTURES) if args.textures == "all" else args.textures.split(",")
    unknown = [n for n in names if n not in TEXTURES]
    if unknown:
        ap.error(f"--textures: no generator texture {', '.join(unknown)} "
                 f"(known: {', '.join(TEXTURES)})")
    if not (math.isfinite(args.load_scale) and args.load_scale > 0):
        ap.error(f"--load-scale: give a positive number, not {args.load_scale}")
    return names, [float(v) for v in args.speeds.split(",")]
