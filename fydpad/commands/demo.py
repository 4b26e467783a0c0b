"""``fydpad demo``: the whole chain on the bundled recordings with the simulated robot."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
import logging
import math
import sys
from pathlib import Path

from fydpad.cli import add_config_argument, add_truncation_argument

DEMO_RECORDINGS = ("circle", "lissajous", "tapping")
DEFAULT_OUT = "fydpad-demo"

#: The paper's own figure (Bianchi et al. 2015, section IV-B, Fig. 11): "MAE is
#: approximately 3 millimeters on all the trials and all the directions" (circle,
#: Lissajous-like curve and tapping, 10 Hz master, KUKA arm).
PAPER_MAE_MM = 3.0

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
    p.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                   help="write each recording's report (JSON) and plot (PNG) here "
                   "(default: %(default)s)")
    p.add_argument("--no-baseline", action="store_true",
                   help="skip the second pass under the paper's condition (faster)")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="show the simulated slave's log (watchdog holds between passes, ...)")
    add_config_argument(p)
    add_truncation_argument(p)
    p.set_defaults(func=run)


def _axes(d: dict | None) -> str:
    if not d:
        return "-"
    return " / ".join("-" if d.get(a) is None or not math.isfinite(d[a]) else f"{d[a]:.2f}"
                      for a in ("x", "y", "z"))


def summary_table(reports: dict[str, dict]) -> list[str]:
    """The end table: per recording, MAE x / y / z (mm) of this run, of the paper's
    condition in the same run, the paper's own figure and against the true finger."""
    head = ("recording", "this run", "paper's condition", "paper's figure", "vs true finger")
    rows = [head]
    paper = " / ".join([f"~{PAPER_MAE_MM:.0f}"] * 3)
    for name, rep in reports.items():
        rows.append((name, _axes(rep.get("mae_mm")), _axes(rep.get("baseline_mae_mm")),
                     paper, _axes(rep.get("truth_mae_mm"))))
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = ["MAE x / y / z (mm): robot against the finger it was sent; the paper's condition "
             "is 10 Hz with the slave holding each sample"]
    for row in rows:
        lines.append("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
    return lines


def dominant_error(reports: dict[str, dict]) -> str:
    """One sentence: what dominates the error, from the reports' own figures."""
    worst = None  # (mm, recording, part, axis)
    link_max = 0.0
    for name, rep in reports.items():
        parts = rep.get("truth_breakdown_mm")
        if parts:
            for part in ("master_vs_truth", "slave_vs_master"):
                for a, v in (parts.get(part) or {}).items():
                    if v is not None and math.isfinite(v) and (worst is None or v > worst[0]):
                        worst = (v, name, part, a)
            link_max = max([link_max] + [v for v in (parts.get("slave_vs_master") or {})
                                         .values() if v is not None and math.isfinite(v)])
        else:
            link_max = max([link_max] + [v for v in rep["mae_mm"].values() if math.isfinite(v)])
            for a, v in (rep.get("truth_mae_mm") or {}).items():
                if v is not None and math.isfinite(v) and (worst is None or v > worst[0]):
                    worst = (v, name, "end_to_end", a)
    base = [max(rep["baseline_mae_mm"].values()) for rep in reports.values()
            if "baseline_mae_mm" in rep]
    paper = (f"; under the paper's condition the 10 Hz hold itself costs up to "
             f"{max(base):.1f} mm" if base else "")
    if worst is None:
        return (f"The robot follows the finger it was sent within {link_max:.2f} mm{paper} "
                "(no truth.csv to say more).")
    v, name, part, a = worst
    if part == "slave_vs_master" or (part == "end_to_end" and v <= 1.5 * link_max):
        return (f"The link and the robot dominate the error: up to {v:.2f} mm on {a} "
                f"({name}){paper}.")
    what = {"x": "the camera tracking (x)", "y": "the camera tracking (y)",
            "z": "the indentation estimate from the IR sensors (z)"}[a]
    return (f"Sensing dominates the error: {what} is off the true finger by {v:.2f} mm on "
            f"{name}, while the link and the robot add at most {link_max:.2f} mm{paper}.")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from fydpad.bundled import bundled_recording
    from fydpad.config import load_config
    from fydpad.plots import plot_teleop
    from fydpad.teleop_run import format_report, recording_states, truth_rows
    from teleop.master import run_local_sim
    from vision.recording import PadRecording
    from vision.strict_json import finite

    if not args.verbose:
        # The in-process slave holds between passes by design: not news in a demo.
        logging.getLogger("teleop").setLevel(logging.ERROR)
    config_path = demo_config_path(args.config)
    config = load_config(config_path)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"device configuration: {config_path or 'the paper defaults'}", flush=True)
    print(f"plots and reports go to {out}/ (--out DIR to choose)", flush=True)
    passes = 1 if args.no_baseline else 2
    reports = {}
    for name in args.recordings:
        rec = PadRecording(bundled_recording(name))
        n = rec.frame_count
        what = ("then under the paper's condition (10 Hz, slave holds)" if passes == 2 else "")
        print(f"{name}: tracking {n} frames, streaming them to the simulated arm in real time "
              f"{what}".rstrip(), flush=True)
        with tqdm(total=n * (1 + passes), desc=name, unit="frame", file=sys.stderr,
                  disable=not sys.stderr.isatty(), dynamic_ncols=True) as bar:
            tick = bar.update
            states = recording_states(rec, config, on_frame=tick)
            session = run_local_sim(states, config.teleop, truth=truth_rows(rec),
                                    baseline=passes == 2, on_sample=tick)
        report = session.report
        reports[name] = report
        print(format_report(name, report), flush=True)
        if "truth_breakdown_mm" in report:
            from teleop.report import breakdown_lines

            print("\n".join(breakdown_lines(report)), flush=True)
        title = f"{name}: MAE x / y / z {_axes(report['mae_mm'])} mm"
        if "baseline_mae_mm" in report:
            title += f" (paper's condition {_axes(report['baseline_mae_mm'])} mm)"
        plot_teleop(out / f"{name}.png", *session.series(), title=title)
        (out / f"{name}.json").write_text(
            json.dumps(finite(report), indent=2, allow_nan=False) + "\n")
    print()
    print("\n".join(summary_table(reports)))
    print(dominant_error(reports))
    print(f"plots: {', '.join(str(out / (n + '.png')) for n in reports)}")
    return 0
