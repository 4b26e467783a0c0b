"""``fydpad track``: the finger's contact in every frame of a recording or a live camera."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from fydpad.cli import add_config_argument, add_truncation_argument
from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only: the modules load inside the functions
    from vision.contact import ContactTracker, TrackerConfig
    from vision.sources import CameraConfig, FrameSource
    from vision.stream import TrackedFrame

#: vision.contact.METHODS, written out so that --help loads no OpenCV
#: (tests/cli/test_fast_help.py keeps the two equal).
TRACKER_METHODS = ("robust", "paper")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="track the finger's contact in a recording or a live camera",
        description=(
            "Track the finger's contact centroid in every frame of a pad session recording "
            "(or a live camera) and write the tracking output of docs/recording_format.md: "
            "t_s,frame,contact,x_mm,y_mm,indentation_mm, one row per frame, written as the "
            "frames are processed (an interrupted run keeps what it had). Where the recording "
            "has truth.csv, the accuracy against it is printed at the end."
        ),
    )
    p.add_argument("recdir", nargs="?", metavar="RECDIR", help="pad session recording directory")
    p.add_argument("--camera", metavar="N", help="track a live camera (index or path) instead")
    p.add_argument("--out", metavar="FILE", required=True, help="tracking output CSV to write")
    p.add_argument("--method", choices=TRACKER_METHODS,
                   help="contact tracker (default: configuration)")
    p.add_argument("--threshold", type=int, help="grey level below which a pixel is the finger")
    p.add_argument("--beta", type=float, help="the paper's beta: sigma = (Imax - Imin) / beta")
    p.add_argument("--plot", metavar="PNG", help="draw the track over time and on the workspace")
    p.add_argument("--video", metavar="MP4", help="write the frames with the contact marked")
    p.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument("--json", metavar="FILE", help="write the summary (and accuracy) as JSON")
    p.add_argument("--calibrated", action="store_true",
                   help="map a recording through the configuration's camera calibration "
                   "(always on for --camera when the configuration has one)")
    add_config_argument(p)
    add_truncation_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from fydpad.config import load_config
    from fydpad.opening import open_source
    from vision.recording import read_track
    from vision.stream import finger_states, live_states
    from vision.strict_json import finite

    config = load_config(args.config)
    tracker_config = config.tracker
    overrides = {
        k: v for k, v in (("method", args.method), ("threshold", args.threshold),
                          ("beta", args.beta)) if v is not None
    }
    try:
        tracker_config = replace(tracker_config, **overrides)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    opened = open_source(config, args.recdir, args.camera)
    source, recording, m = opened.source, opened.recording, opened.meta
    total = opened.total_frames
    use_calibration = args.camera is not None or args.calibrated
    tracker = make_tracker(tracker_config, m.roi_px, m.workspace_mm, m.image_flip,
                           config.camera if use_calibration else None)
    if args.calibrated and config.camera.workspace_homography is None:
        raise UserError("--calibrated: the configuration has no [camera.workspace_homography] "
                        "(run 'fydpad calibrate workspace' first)")

    truth = recording.read_truth() if recording is not None else None
    if args.max_frames is not None:
        total = min(total or args.max_frames, args.max_frames)
    stream = (finger_states(recording, tracker, config.ir, source.frames())
              if recording is not None else live_states(source.frames(), tracker))
    n_written = track_to_csv(
        stream, source, tracker, Path(args.out), total=total, video=args.video, truth=truth,
        max_frames=args.max_frames,
    )
    cols = read_track(Path(args.out))  # what was written, read once for summary and plot
    summary = summarise(cols, str(args.out), truth, n_written, tracker)
    if args.plot:
        _plot(Path(args.plot), cols, m.workspace_mm, truth, str(source))
    print(format_summary(summary))
    if args.json:
        Path(args.json).write_text(
            json.dumps(finite(summary), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return 0


def make_tracker(
    cfg: TrackerConfig,
    roi_px: tuple[int, int, int, int],
    workspace_mm: tuple[float, float],
    image_flip: str,
    camera: CameraConfig | None = None,
) -> ContactTracker:
    """The configured tracker; with ``camera``, its lens and workspace calibration apply."""
    from vision.calibration import CalibratedMapping
    from vision.contact import ContactTracker

    calibration = None
    if camera is not None and camera.workspace_homography is not None:
        calibration = CalibratedMapping(camera.workspace_homography, camera.intrinsics,
                                        image_flip)
    return ContactTracker(
        roi_px=roi_px, workspace_mm=workspace_mm, image_flip=image_flip, method=cfg.method,
        threshold=cfg.threshold, beta=cfg.beta, processing_size=cfg.processing_size,
        robust=cfg.robust, calibration=calibration,
    )


def track_to_csv(
    stream: Iterator[TrackedFrame],
    source: FrameSource,
    tracker: ContactTracker,
    out: Path,
    total: int | None = None,
    video: str | None = None,
    truth=None,
    max_frames: int | None = None,
) -> int:
    """Write the tracked ``stream`` into ``out``, row by row; returns the rows written."""
    from fydpad.annotate import AnnotatedVideoWriter, annotate_frame
    from fydpad.progress import progress
    from vision.recording import TrackWriter
    from vision.sources import SourceError

    writer = TrackWriter(out, extra_columns=("u_px", "v_px", "area_mm2", "speed_mm_s"))
    annotated = None
    n = 0
    try:
        for tracked in progress(stream, total=total, desc="tracking"):
            if max_frames is not None and n >= max_frames:
                break
            frame, contact, state = tracked.frame, tracked.contact, tracked.state
            if contact is None:
                writer.write_row(frame.t_s, frame.index, False, None, None,
                                 state.indentation_mm, None, None, None, None)
            else:
                writer.write_row(frame.t_s, frame.index, True, contact.x_mm, contact.y_mm,
                                 state.indentation_mm, contact.u_px, contact.v_px,
                                 contact.area_mm2, state.speed_mm_s)
            if video:
                if annotated is None:
                    h, w = frame.image.shape[:2]
                    annotated = AnnotatedVideoWriter(video, source.fps, (w, h))
                truth_uv = _truth_uv(truth, frame.index, tracker)
                annotated.write(annotate_frame(frame.image, tracker.image_flip, tracker.roi_px,
                                               contact, truth_uv, f"#{frame.index}"))
            n += 1
    except KeyboardInterrupt:
        print(f"interrupted: {out} keeps the {n} frames tracked so far", file=sys.stderr)
        raise
    except SourceError as exc:
        raise UserError(f"{exc} ({out} keeps the {n} frames tracked so far)") from None
    finally:
        writer.close()
        source.close()
        if annotated is not None:
            annotated.close()
    return n


def _truth_uv(truth, k: int, tracker: ContactTracker) -> tuple[float, float] | None:
    from vision.mapping import workspace_to_roi

    if truth is None or k >= truth.contact.size or not truth.contact[k]:
        return None
    u, v = workspace_to_roi(truth.x_mm[k], truth.y_mm[k], tracker.roi_px, tracker.workspace_mm)
    return float(u), float(v)


def summarise(cols: dict, out: str, truth, n_written: int, tracker: ContactTracker) -> dict:
    import numpy as np

    from vision.evaluation import score_tracking

    summary: dict = {
        "output": str(out),
        "method": tracker.method,
        "frames": n_written,
        "contact_frames": int(np.count_nonzero(cols["contact"])),
    }
    if truth is not None:
        n = min(n_written, truth.contact.size)
        score = score_tracking(
            cols["contact"][:n] != 0, cols["x_mm"][:n], cols["y_mm"][:n],
            truth.contact[:n], truth.x_mm[:n], truth.y_mm[:n],
        )
        summary["truth"] = score.as_dict()
    return summary


def format_summary(s: dict) -> str:
    lines = [
        f"tracked {s['frames']} frames with method '{s['method']}': "
        f"{s['contact_frames']} with contact -> {s['output']}"
    ]
    if "truth" in s:
        t = s["truth"]
        lines.append(
            f"against truth.csv: RMSE {t['rmse_mm']:.3f} mm (max {t['max_error_mm']:.2f} mm) "
            f"over {t['contact_frames']} contact frames; missed {t['missed']}, "
            f"false {t['false']}"
        )
    return "\n".join(lines)


def _plot(path: Path, cols: dict, workspace_mm, truth, title: str) -> None:
    from fydpad.plots import plot_track

    truth_dict = None
    if truth is not None:
        truth_dict = {"t_s": truth.t_s, "x_mm": truth.x_mm, "y_mm": truth.y_mm,
                      "indentation_mm": truth.indentation_mm}
    plot_track(path, cols["t_s"], cols["x_mm"], cols["y_mm"], cols["indentation_mm"],
               workspace_mm, truth_dict, title=title)
