"""``fydpad replay``: a recording tracked and streamed to a slave robot, with the report."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
from pathlib import Path

from fydpad.cli import add_config_argument, add_truncation_argument
from fydpad.commands.run import add_link_arguments, apply_link_arguments
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
            "lag, link latency, and where the recording has truth.csv the error against the "
            "true finger, broken down (printed first): the tracked x, y and the indentation "
            "against the truth, the slave against the master stream, the slave against the "
            "truth."
        ),
    )
    p.add_argument("recdir", metavar="RECDIR", help="pad session recording")
    p.add_argument("--teleop", metavar="ENDPOINT", required=True,
                   help="the slave's ZeroMQ endpoint, e.g. tcp://10.0.0.5:5555 or "
                   "10.0.0.5:5555")
    add_link_arguments(p)
    p.add_argument("--report", metavar="REPORT.json", required=True, help="report to write")
    p.add_argument("--plot", metavar="PNG", help="master and slave per axis over time (Fig. 11)")
    p.add_argument("--slave-log", metavar="CSV",
                   help="write the slave's command and actual position per tick on the "
                   "recording's clock (for `fydpad export bag --slave-log`)")
    p.add_argument("--no-baseline", action="store_true",
                   help="skip the second pass under the paper's condition")
    add_config_argument(p)
    add_truncation_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fydpad.config import load_config
    from fydpad.teleop_run import format_report, recording_states, truth_rows
    from teleop.master import run_session
    from teleop.report import breakdown_lines
    from vision.recording import PadRecording
    from vision.strict_json import finite

    config = load_config(args.config)
    apply_link_arguments(args, config)
    rec = PadRecording(args.recdir)
    states = recording_states(rec, config)
    try:
        session = run_session(states, args.teleop, config.teleop, truth=truth_rows(rec),
                              baseline=not args.no_baseline)
    except (TimeoutError, OSError, ValueError) as exc:
        raise UserError(f"--teleop {args.teleop}: {exc}") from None
    Path(args.report).write_text(
        json.dumps(finite(session.report), indent=2, allow_nan=False) + "\n")
    if args.slave_log:
        from fydpad.export.slave_log import write_slave_log

        write_slave_log(session, args.slave_log)
    if args.plot:
        from fydpad.plots import plot_teleop

        mae = " / ".join(f"{session.report['mae_mm'][a]:.2f}" for a in "xyz")
        plot_teleop(args.plot, *session.series(), title=f"{rec.path.name}: MAE x / y / z {mae} mm")
    # Where the error against the truth comes from first: the largest part is named.
    for line in breakdown_lines(session.report):
        print(line)
    print(format_report(rec.path.name, session.report))
    return 0
