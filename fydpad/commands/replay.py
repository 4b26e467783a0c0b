"""``fydpad replay``: a recording tracked and streamed to a slave robot, with the report."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
from pathlib import Path

from fydpad.cli import add_config_argument
from fydpad.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="stream a recording's finger track to a slave robot and report the error",
        description=(
            "Track a pad session recording, stream the finger states to a slave robot "
            "(`teleop slave`) at the recording's own frame rate, collect the slave's actual "
            "positions and write the tele-operation report of docs/recording_format.md: MAE per "
            "axis (eq. 6), the same under the paper's condition (10 Hz master, slave holds), "
            "lag, link latency, and the error against the true finger where the recording "
            "has truth.csv."
        ),
    )
    p.add_argument("recdir", metavar="RECDIR", help="pad session recording")
    p.add_argument("--teleop", metavar="ENDPOINT", required=True,
                   help="the slave's ZeroMQ endpoint, e.g. tcp://127.0.0.1:5555")
    p.add_argument("--report", metavar="REPORT.json", required=True, help="report to write")
    p.add_argument("--plot", metavar="PNG", help="master and slave per axis over time (Fig. 11)")
    p.add_argument("--no-baseline", action="store_true",
                   help="skip the second pass under the paper's condition")
    add_config_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fydpad.config import load_config
    from fydpad.teleop_run import format_report, recording_states, truth_rows
    from teleop.master import run_session
    from vision.recording import PadRecording

    config = load_config(args.config)
    rec = PadRecording(args.recdir)
    states = recording_states(rec, config)
    try:
        session = run_session(states, args.teleop, config.teleop, truth=truth_rows(rec),
                              baseline=not args.no_baseline)
    except TimeoutError as exc:
        raise UserError(str(exc)) from None
    Path(args.report).write_text(json.dumps(session.report, indent=2) + "\n")
    if args.plot:
        session.plot(args.plot, title=rec.path.name)
    print(format_report(rec.path.name, session.report))
    return 0
