"""``fydpad synth``: write a synthetic pad session recording with ground truth."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only: the synthetic pad (OpenCV, NumPy) loads in the command
    from fydpad.synth import SynthConfig

# The synthetic pad's option lists, written out so that --help loads neither OpenCV nor
# NumPy (tests/cli/test_fast_help.py keeps each equal to its source).
#: fydpad.synth.TRAJECTORIES
TRAJECTORIES = ("circle", "lissajous", "tapping", "walk", "fast", "hover", "presses",
                "protocol")
#: vision.recording.IMAGE_FLIPS and VIDEO_NAMES
IMAGE_FLIPS = ("none", "horizontal", "vertical", "both")
VIDEO_NAMES = ("video.avi", "video.mp4")
#: fydpad.synth.EFFECT_HELP
EFFECT_HELP: dict[str, str] = {
    "uneven_light": "uneven, strongly vignetted backlight (corners ~35 % darker, a lamp's "
                    "hotspot, blotches)",
    "room_light": "room light dipping by a third for seconds, mains flicker and bursts",
    "auto_exposure": "camera auto-exposure hunting: the whole image swings by up to +-20 %",
    "daylight": "daylight from one side: a brightness gradient whose side and strength drift",
    "stains": "ink dots, pen lines and a dried stain on the fabric, darker than grey 150",
    "hover": "the finger travels 3 mm above the fabric between contacts and its shadow is dark "
             "(below grey 150 when close)",
    "hand_shadow": "the rest of the hand shadows the user's edge of the view",
    "light_touch": "light touches: indentations under ~1.5 mm and a pale contact",
    "fast": "fast strokes: finger speed up to 45 mm/s and a 1/30 s exposure",
    "palm_rest": "the heel of the palm rests on the fabric at the user's edge at the start, "
                 "lifted after 1-2 s",
}

#: The files of a pad session recording (docs/recording_format.md), removed by --force.
RECORDING_FILES = ("meta.json", *VIDEO_NAMES, "frames.csv", "ir.csv", "force.csv", "truth.csv")

_TRAJECTORY_HELP = (
    "circle: the paper's tele-operation circle (r 25 mm, up to 40 mm/s, 2.5-7.5 mm deep); "
    "lissajous: a 3:2 Lissajous curve over the workspace; "
    "tapping: taps at random places 10-50 mm deep at up to 80 mm/s; "
    "walk: smooth random strokes, 2-20 mm deep, with lifts; "
    "fast: straight strokes across the workspace at 45 mm/s; "
    "hover: a finger moving 1.5-8 mm above the fabric, touching now and then"
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synth",
        help="write a synthetic pad session recording with ground truth",
        description=(
            "Render a pad session recording (meta.json, video, ir.csv, force.csv, truth.csv; "
            "docs/recording_format.md) from the project's physical model: backlit woven fabric "
            "seen from below, a dark fingertip contact growing with indentation and the "
            "paler shadow of the finger, vignetting, sensor noise, motion blur over the "
            "exposure, MJPG compression; IR voltages from the fabric's non-planar sag "
            "through the inverse of the paper's eq. (1) with a 10-bit ADC; load-cell "
            "force from the fabric's stiffness. Every trajectory starts with ~0.8 s "
            "without contact (IR baselines). The same seed gives the same recording."
        ),
        epilog="Effects can be combined freely; --all-effects turns every one on.",
    )
    p.add_argument("outdir", metavar="OUTDIR", help="directory to write (created if needed)")
    p.add_argument("--force", action="store_true",
                   help="replace the recording OUTDIR already holds (only the files of a "
                        "recording are removed)")
    p.add_argument("--trajectory", choices=TRAJECTORIES, default="circle",
                   help=f"finger path (default: %(default)s). {_TRAJECTORY_HELP}")
    p.add_argument("--seconds", type=float, default=10.0,
                   help="duration in seconds (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0,
                   help="random seed: the same seed gives the same recording "
                        "(default: %(default)s)")
    p.add_argument("--fps", type=float, default=30.0,
                   help="camera frame rate (default: %(default)s)")
    p.add_argument("--exposure", type=float, default=None, metavar="S",
                   help="exposure time in seconds (default: 1/60, or 1/30 with --fast)")
    p.add_argument("--flip", choices=IMAGE_FLIPS, default="horizontal",
                   help="how the camera's raw frame is mirrored relative to the fabric seen "
                        "from above; written as image_flip in meta.json (default: %(default)s, "
                        "a camera looking up at the fabric)")
    p.add_argument("--video", choices=VIDEO_NAMES, default="video.avi",
                   help="video file: video.avi is MJPG as the webcam gives it, video.mp4 is "
                        "mp4v, several times smaller (default: %(default)s)")
    p.add_argument("--mjpg-quality", type=int, default=80, metavar="Q",
                   help="JPEG quality of the webcam's own MJPG compression, applied to every "
                        "frame before the video is written; 0 turns it off "
                        "(default: %(default)s)")
    g = p.add_argument_group("effects (conditions of real footage; combinable)")
    for name, text in EFFECT_HELP.items():
        g.add_argument(f"--{name.replace('_', '-')}", dest=name, action="store_true",
                       help=text.replace("%", "%%"))
    g.add_argument("--all-effects", action="store_true", help="every effect above at once")
    p.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> SynthConfig:
    from fydpad.synth import Effects, SynthConfig  # the synthetic pad: not for --help

    if not args.seconds > 0:
        raise UserError(f"--seconds must be positive, got {args.seconds}")
    if not args.fps > 0:
        raise UserError(f"--fps must be positive, got {args.fps}")
    if args.exposure is not None and not 0 < args.exposure <= 1.0 / args.fps:
        raise UserError(f"--exposure must be in (0, 1/fps = {1.0 / args.fps:.4g}] s, "
                        f"got {args.exposure}")
    if not 0 <= args.mjpg_quality <= 100:
        raise UserError(f"--mjpg-quality must be in 0..100, got {args.mjpg_quality}")
    if args.all_effects:
        effects = Effects.all()
    else:
        effects = Effects(**{name: bool(getattr(args, name)) for name in EFFECT_HELP})
    return SynthConfig(
        trajectory=args.trajectory, seconds=args.seconds, seed=args.seed, effects=effects,
        image_flip=args.flip, fps=args.fps, exposure_s=args.exposure,
        mjpg_quality=args.mjpg_quality or None,
    )


def run(args: argparse.Namespace) -> int:
    from fydpad.progress import progress  # tqdm: not for --help
    from fydpad.synth import SyntheticPad  # OpenCV, NumPy: not for --help

    cfg = config_from_args(args)
    out = Path(args.outdir)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a directory")
    existing = [out / n for n in RECORDING_FILES if (out / n).exists()]
    if existing and not args.force:
        raise UserError(f"{out}: already holds a recording ({existing[0].name}); "
                        "pass --force to replace it")
    for path in existing:
        path.unlink()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{out}: cannot be created ({exc.strerror})") from None
    start = time.monotonic()
    pad = SyntheticPad(cfg)
    pad.write(out, video_name=args.video,
              progress=lambda it, n: progress(it, total=n, desc="synth"))
    effects = ", ".join(cfg.effects.names()) or "none"
    print(f"wrote {out}: {cfg.trajectory}, {pad.frame_count} frames, {cfg.seconds:g} s, "
          f"seed {cfg.seed}, effects: {effects} ({time.monotonic() - start:.1f} s)",
          file=sys.stdout)
    return 0
