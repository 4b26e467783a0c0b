"""Tracking a recording and streaming it to a slave: shared by ``fydpad replay`` and
``fydpad demo``."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fydpad.commands.track import make_tracker
from fydpad.config import StationConfig
from fydpad.progress import progress
from vision.recording import PadRecording
from vision.state import FingerState
from vision.stream import finger_states


def recording_states(rec: PadRecording, config: StationConfig,
                     on_frame: Callable[[], None] | None = None) -> list[FingerState]:
    """The finger state of every frame (tracked first, so streaming is paced exactly);
    ``on_frame`` is called after each (a caller's own progress bar), else a bar of its own."""
    m = rec.meta
    tracker = make_tracker(config.tracker, m.roi_px, m.workspace_mm, m.image_flip)
    frames = finger_states(rec, tracker, config.ir)
    if on_frame is None:
        return [tf.state for tf in progress(frames, total=rec.frame_count, desc="tracking")]
    states = []
    for tf in frames:
        states.append(tf.state)
        on_frame()
    return states


def truth_rows(rec: PadRecording) -> np.ndarray | None:
    """truth.csv as rows ``t_s, contact, x_mm, y_mm, indentation_mm`` (teleop's layout)."""
    t = rec.read_truth()
    if t is None:
        return None
    return np.column_stack([t.t_s, t.contact.astype(float), t.x_mm, t.y_mm, t.indentation_mm])


def format_report(name: str, report: dict) -> str:
    def axes(d: dict) -> str:
        return " / ".join(f"{d[a]:.2f}" for a in ("x", "y", "z"))

    lines = [f"{name}: MAE x/y/z {axes(report['mae_mm'])} mm"]
    if "baseline_mae_mm" in report:
        lines[0] += f"   (paper's condition, 10 Hz hold: {axes(report['baseline_mae_mm'])} mm)"
    if "truth_mae_mm" in report:
        lines.append(f"  against the true finger: {axes(report['truth_mae_mm'])} mm")
    lat = report["latency_ms"]
    lines.append(f"  lag {report['lag_ms']:.0f} ms, link latency p50 {lat['p50']:.2f} ms "
                 f"p99 {lat['p99']:.2f} ms, {report['samples']} samples, "
                 f"{report['dropped']} dropped, {report['duration_s']:.1f} s")
    return "\n".join(lines)
