"""``fydpad demo``: the whole chain on the bundled recordings with the simulated robot."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
import logging
from pathlib import Path

from fydpad.cli import add_config_argument

DEMO_RECORDINGS = ("circle", "lissajous", "tapping")

#: The bundled recordings' device configuration (its indentation calibration), made once
#: by ``python recordings/make_recordings.py --calibration`` from sessions of its own.
DEVICE_CONFIG = "device.toml"


def demo_config_path(given: str | None) -> Path | None:
    """The device configuration of the demo: the one given, else the bundled device's."""
    from fydpad.bundled import recordings_dir

    if given is not None:
        return Path(given)
    path = recordings_dir() / DEVICE_CONFIG
    return path if path.is_file() else None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="the whole chain on the bundled recordings with the simulated robot",
        description=(
            "Run the whole chain on the bundled recordings (the paper's circle, Lissajous-like "
            "curve and tapping): track the finger in the under-fabric video, estimate the "
            "indentation from the IR sensors, stream the finger to a simulated KUKA iiwa arm "
            "(PyBullet) over a real ZeroMQ loopback socket, and print the tele-operation "
            "report: MAE per axis against the paper's condition, and against the true finger. "
            "The device configuration is the bundled recordings' own (recordings/device.toml: "
            "the synthetic device's indentation calibration) unless --config is given."
        ),
    )
    p.add_argument("--recordings", nargs="+", default=list(DEMO_RECORDINGS), metavar="NAME",
                   help="bundled recordings to run (default: %(default)s)")
    p.add_argument("--out", metavar="DIR", help="write each report (JSON) and plot (PNG) here")
    p.add_argument("--no-baseline", action="store_true",
                   help="skip the second pass under the paper's condition (faster)")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="show the simulated slave's log (watchdog holds between passes, ...)")
    add_config_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fydpad.bundled import bundled_recording
    from fydpad.config import load_config
    from fydpad.teleop_run import format_report, recording_states, truth_rows
    from teleop.master import run_local_sim
    from vision.recording import PadRecording

    if not args.verbose:
        # The in-process slave holds between passes by design: not news in a demo.
        logging.getLogger("teleop").setLevel(logging.ERROR)
    config_path = demo_config_path(args.config)
    config = load_config(config_path)
    print(f"device configuration: {config_path or 'the paper defaults'}", flush=True)
    out = Path(args.out) if args.out else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    reports = {}
    for name in args.recordings:
        rec = PadRecording(bundled_recording(name))
        states = recording_states(rec, config)
        session = run_local_sim(
            states, config.teleop, truth=truth_rows(rec), baseline=not args.no_baseline,
            plot_path=str(out / f"{name}.png") if out is not None else None,
        )
        reports[name] = session.report
        print(format_report(name, session.report), flush=True)
        if out is not None:
            (out / f"{name}.json").write_text(json.dumps(session.report, indent=2) + "\n")
    return 0
