"""``fydpad demo``: the whole chain on the bundled recordings, with the figures printed."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from fydpad.bundled import bundled_recording
from fydpad.cli import add_config_argument
from fydpad.commands.track import format_summary, make_tracker, summarise, track_to_csv
from fydpad.config import load_config
from vision.recording import PadRecording
from vision.sources import VideoSource
from vision.stream import finger_states

DEMO_RECORDINGS = ("circle", "lissajous", "tapping")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run the whole chain on the bundled recordings and print the figures",
        description=(
            "Track the finger in the bundled recordings (circle, Lissajous-like curve, tapping) "
            "and print the accuracy against their ground truth."
        ),
    )
    p.add_argument("--recordings", nargs="+", default=list(DEMO_RECORDINGS), metavar="NAME",
                   help="bundled recordings to run (default: %(default)s)")
    p.add_argument("--out", metavar="DIR", help="keep the outputs here (default: a temp dir)")
    add_config_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    with tempfile.TemporaryDirectory(prefix="fydpad-demo-") as tmp:
        out_dir = Path(args.out) if args.out else Path(tmp)
        out_dir.mkdir(parents=True, exist_ok=True)
        for name in args.recordings:
            rec = PadRecording(bundled_recording(name))
            m = rec.meta
            tracker = make_tracker(config.tracker, m.roi_px, m.workspace_mm, m.image_flip)
            out = out_dir / f"{name}_track.csv"
            source = VideoSource(rec)
            n = track_to_csv(finger_states(rec, tracker, config.ir, source.frames()), source,
                             tracker, out, total=rec.frame_count)
            print(f"== {name}")
            print(format_summary(summarise(out, rec.read_truth(), n, tracker)))
    return 0
