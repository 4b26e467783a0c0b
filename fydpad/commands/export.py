"""``fydpad export bag``: a pad session recording as a ROS 2 bag (MCAP), docs/ros.md."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from fydpad.cli import add_config_argument
from fydpad.config import load_config
from fydpad.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="export a recording into other tools' formats (a ROS 2 bag)",
        description="Export a pad session recording into other tools' formats.",
    )
    what = p.add_subparsers(dest="format", metavar="FORMAT", required=True)
    b = what.add_parser(
        "bag",
        help="a rosbag2 in MCAP storage: ros2 bag play, Foxglove, rerun (docs/ros.md)",
        description=(
            "Write a pad session recording as a ROS 2 bag (rosbag2, MCAP storage) with "
            "standard message types: the finger (PoseStamped in fydpad_workspace, contact, "
            "indentation), the true finger where truth.csv has it, force (WrenchStamped), the "
            "camera (CompressedImage, JPEG), the IR voltages and distances (Range), the "
            "rendered vibration (commands.csv), the slave's command and actual pose "
            "(slave.csv, `fydpad replay --slave-log`), and /tf_static for the workspace, the "
            "robot base and the IR sensors. Stamps are the recording's clock. The finger "
            "comes from RECDIR/track.csv (`fydpad run --record` writes it) or --track; "
            "without either the video is tracked first. Needs the ros extra: "
            "pip install 'fydpad[ros]'. Topic list and conventions: docs/ros.md."
        ),
    )
    b.add_argument("recdir", metavar="RECDIR", help="pad session recording")
    b.add_argument("--out", metavar="BAGDIR", required=True,
                   help="bag directory to create (must not exist)")
    b.add_argument("--track", metavar="CSV",
                   help="tracking output (`fydpad track`); default RECDIR/track.csv")
    b.add_argument("--slave-log", metavar="CSV",
                   help="the slave's log (`fydpad replay --slave-log`); default RECDIR/slave.csv")
    b.add_argument("--no-video", action="store_true", help="leave the camera out")
    add_config_argument(b)
    b.set_defaults(func=run_bag)


def require_rosbags() -> None:
    """A one-line error when the ros extra is not installed."""
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise UserError("the ROS 2 bag export needs the rosbags package: "
                        "pip install 'fydpad[ros]'") from None


def track_columns(recdir: Path, config) -> dict:
    """The tracking output's columns for a recording without track.csv (tracked now)."""
    import numpy as np

    from fydpad.teleop_run import recording_states
    from vision.recording import PadRecording

    rec = PadRecording(recdir)
    states = recording_states(rec, config)
    times = rec.frame_times()
    return {
        "t_s": np.asarray(times[: len(states)], float),
        "contact": np.array([1.0 if s.contact else 0.0 for s in states]),
        "x_mm": np.array([s.x_mm if s.contact else np.nan for s in states]),
        "y_mm": np.array([s.y_mm if s.contact else np.nan for s in states]),
        "indentation_mm": np.array([(s.indentation_mm if s.contact else 0.0)
                                    for s in states]),
    }


def export_recording(recdir: str, out: str, config_path: str | None, **kw) -> str:
    """Export and return the one-line summary (shared with ``fydpad run --bag``)."""
    from fydpad.export.bag import export_bag

    require_rosbags()
    config = load_config(config_path)
    t0 = time.perf_counter()
    summary = export_bag(recdir, out, config,
                         track_video=lambda: track_columns(Path(recdir), config), **kw)
    size_mb = sum(f.stat().st_size for f in summary.path.rglob("*") if f.is_file()) / 1e6
    early = (f" ({summary.before_start} samples stamped before t_s = 0 left out)"
             if summary.before_start else "")
    return (f"{summary.path}: {summary.messages} messages on {len(summary.counts)} topics, "
            f"{size_mb:.1f} MB, in {time.perf_counter() - t0:.1f} s{early}")


def run_bag(args: argparse.Namespace) -> int:
    print(export_recording(args.recdir, args.out, args.config, track=args.track,
                           slave_log=args.slave_log, video=not args.no_video))
    return 0
