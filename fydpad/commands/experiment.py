"""``fydpad experiment``: reports of the absolute identification experiment (Table I)."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
from pathlib import Path

from fydpad.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "experiment",
        help="the absolute identification experiment: report the results",
        description=(
            "The paper's absolute identification task (section IV-C) runs from the "
            "station's web view (`fydpad run --web PORT`, page /experiment). This command "
            "reports a results directory: the confusion matrix over all participants, the "
            "relative accuracy per specimen and the average against chance, like Table I."
        ),
    )
    esub = p.add_subparsers(dest="experiment_command", metavar="ACTION", required=True)
    r = esub.add_parser("report", help="confusion matrix and accuracies of a results directory")
    r.add_argument("results_dir", metavar="RESULTS_DIR")
    r.add_argument("--plot", metavar="PNG", help="also write the confusion matrix plot "
                   "(default: RESULTS_DIR/confusion.png)")
    r.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    r.set_defaults(func=run_report)


def run_report(args: argparse.Namespace) -> int:
    from fydpad.web.experiment import ExperimentError, plot_confusion, report
    from vision.strict_json import finite

    try:
        conf, participants = report(args.results_dir)
    except ExperimentError as exc:
        raise UserError(str(exc)) from None
    print(f"{len(participants)} participant(s): {', '.join(participants)}")
    print(conf.table())
    png = Path(args.plot) if args.plot else Path(args.results_dir) / "confusion.png"
    plot_confusion(conf, png)
    print(f"plot: {png}")
    if args.json:
        summary = finite({"participants": participants, **conf.as_dict()})
        Path(args.json).write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return 0
