"""``fydpad calibrate camera`` and ``fydpad calibrate workspace``: the camera's lens and
the image-to-workspace homography, saved into the device configuration."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from fydpad.cli import add_config_argument, add_truncation_argument
from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only: the modules load inside the functions
    import numpy as np

    from fydpad.config import StationConfig
    from vision.calibration import CharucoBoardSpec
    from vision.sources import FrameSource

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def register_camera(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "camera",
        help="the webcam's lens (intrinsics and distortion) from views of a ChArUco board",
        description=(
            "Fit the camera matrix and lens distortion from views of a ChArUco board "
            "(opencv-contrib's aruco module). Done once per camera: hold the printed board "
            "in front of the camera at 10-20 positions and tilts covering the whole view, and "
            "save the frames as images in a directory or as a video. The result is written "
            "into the configuration (section [camera.intrinsics]); the tracker then "
            "undistorts contact positions."
        ),
    )
    p.add_argument("source", metavar="IMAGES", nargs="?",
                   help="a directory of images, or a video file")
    p.add_argument("--board", default="7x5", metavar="COLSxROWS",
                   help="squares across and down (default: %(default)s)")
    p.add_argument("--square-mm", type=float, default=12.0, help="square side (default: 12)")
    p.add_argument("--marker-mm", type=float, default=9.0, help="marker side (default: 9)")
    p.add_argument("--dictionary", default="DICT_5X5_100",
                   help="ArUco dictionary of the board (default: %(default)s)")
    p.add_argument("--every", type=int, default=10, metavar="N",
                   help="from a video, use every N-th frame (default: %(default)s)")
    p.add_argument("--out", metavar="TOML",
                   help="configuration file to write (the --config file updated, or new)")
    p.add_argument("--example", metavar="DIR",
                   help="write sample board views (DIR/charuco/, rendered through a known "
                        "wide-angle lens) to try the command on, and exit")
    add_config_argument(p)
    p.set_defaults(func=run_camera)


def register_workspace(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "workspace",
        help="the image-to-workspace mapping from presses at marked points",
        description=(
            "Fit the homography from the (undistorted) image to the workspace from presses "
            "at marked points: a square grid over 80%% of the workspace (9 points by default), "
            "pressed in reading order as seen from above (far row first, left to right), each "
            "held still for about a second. From a recording of those presses, or live from a "
            "camera. The result is written into the configuration (section "
            "[camera.workspace_homography]) and used instead of the linear ROI mapping."
        ),
    )
    p.add_argument("recdir", nargs="?", metavar="RECDIR", help="a recording of the presses")
    p.add_argument("--camera", metavar="N", help="calibrate live from this camera instead")
    p.add_argument("--points", type=int, default=9, help="number of marked points (a square)")
    p.add_argument("--min-hold-s", type=float, default=0.4,
                   help="shortest press that counts (default: %(default)s s)")
    p.add_argument("--out", metavar="TOML", required=True,
                   help="configuration file to write (the --config file updated, or new)")
    add_config_argument(p)
    add_truncation_argument(p)
    p.set_defaults(func=run_workspace)


# --------------------------------------------------------------------------- camera


def _board_spec(args: argparse.Namespace) -> CharucoBoardSpec:
    from vision.calibration import CharucoBoardSpec

    try:
        cols, rows = (int(v) for v in args.board.lower().split("x"))
    except ValueError:
        raise UserError(f"--board: expected COLSxROWS such as 7x5, got {args.board!r}") from None
    if args.marker_mm >= args.square_mm:
        raise UserError("--marker-mm must be smaller than --square-mm")
    return CharucoBoardSpec(cols, rows, args.square_mm, args.marker_mm, args.dictionary)


def _calibration_images(source: Path, every: int) -> Iterator[np.ndarray]:
    import cv2

    from fydpad.progress import progress

    if source.is_dir():
        files = sorted(p for p in source.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise UserError(f"{source}: no images ({', '.join(IMAGE_SUFFIXES)})")
        for f in progress(files, total=len(files), desc="board views"):
            image = cv2.imread(str(f))
            if image is None:
                raise UserError(f"{f}: OpenCV cannot read it as an image")
            yield image
        return
    if not source.exists():
        raise UserError(f"{source}: no such directory or video")
    cap = cv2.VideoCapture(str(source))
    if not cap.isOpened():
        raise UserError(f"{source}: OpenCV cannot open it as a video")
    try:
        k = 0
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            if k % max(1, every) == 0:
                yield frame
            k += 1
    finally:
        cap.release()


def run_camera(args: argparse.Namespace) -> int:
    from fydpad.config import load_config, save_config
    from vision.calibration import CalibrationError, calibrate_charuco

    if args.example:
        from fydpad.calibration_examples import write_camera_example

        folder = write_camera_example(Path(args.example))
        print(f"wrote {folder}/ ({len(list(folder.glob('*.png')))} board views): fit them "
              f"with `fydpad calibrate camera {folder} --out camera.toml`")
        return 0
    if args.source is None or args.out is None:
        raise UserError("calibrate camera: give IMAGES and --out TOML (or --example DIR for "
                        "sample board views)")
    config = load_config(args.config)
    spec = _board_spec(args)
    try:
        spec.board()
        intrinsics, used = calibrate_charuco(_calibration_images(Path(args.source), args.every),
                                             spec)
    except CalibrationError as exc:
        raise UserError(f"{args.source}: {exc}") from None
    config.camera = replace(config.camera, intrinsics=intrinsics)
    save_config(config, args.out)
    k = intrinsics.k
    print(f"lens calibrated from {used} board views: reprojection RMS {intrinsics.rms_px:.3f} px")
    print(f"  focal length {k[0, 0]:.1f} x {k[1, 1]:.1f} px, centre ({k[0, 2]:.1f}, "
          f"{k[1, 2]:.1f}) px, distortion {', '.join(f'{d:+.4f}' for d in intrinsics.dist)}")
    print(f"written to {args.out} [camera.intrinsics]")
    return 0


# --------------------------------------------------------------------------- workspace


def run_workspace(args: argparse.Namespace) -> int:
    from fydpad.config import load_config, save_config
    from fydpad.opening import open_source
    from vision.calibration import CalibrationError, default_targets_mm

    config = load_config(args.config)
    opened = open_source(config, args.recdir, args.camera)
    m = opened.meta
    # The recording's geometry (or the camera's configuration) is the one calibrated.
    camera = opened.camera or replace(config.camera, roi_px=m.roi_px,
                                      workspace_mm=m.workspace_mm, image_flip=m.image_flip)
    try:
        targets = default_targets_mm(m.workspace_mm, args.points)
    except CalibrationError as exc:
        raise UserError(f"--points: {exc}") from None
    source, total = opened.source, opened.total_frames
    if opened.camera is not None:
        print("keep the fabric clear for a second, then press each point in turn, holding "
              "still for about a second:")
        for i, (x, y) in enumerate(targets):
            print(f"  point {i + 1}: x {x:+.1f} mm, y {y:+.1f} mm")
    homography, residual = fit_from_presses(source, camera, config, targets, args.min_hold_s,
                                            total)
    config.camera = replace(camera, workspace_homography=homography)
    save_config(config, args.out)
    print(f"workspace mapping fitted from {len(targets)} presses: RMS {homography.rms_mm:.3f} mm, "
          f"worst point {residual.max():.3f} mm")
    print(f"written to {args.out} [camera.workspace_homography]")
    return 0


def match_presses(t, c, u, v, x, y, targets: np.ndarray,
                  min_hold_s: float) -> list[tuple[float, float]]:
    """Each marked point's press in the image (flipped-frame pixels), in target order.

    Every press held ``min_hold_s`` is given to the marked point nearest where the
    uncalibrated (linear ROI) mapping puts it, if within half the points' spacing; a point
    pressed in several rounds gets the median of its presses. So a session of any length
    serves, in any order, as long as it presses every point; otherwise the error names
    the points no press matched."""
    import numpy as np  # loaded when the command runs (fast --help)

    from vision.calibration import press_centroids

    uv = press_centroids(t, c, u, v, min_hold_s)
    xy = np.asarray(press_centroids(t, c, x, y, min_hold_s), float).reshape(-1, 2)
    gaps = np.hypot(*(targets[:, None, :] - targets[None, :, :]).transpose(2, 0, 1))
    radius_mm = 0.5 * gaps[gaps > 0].min() if len(targets) > 1 else np.inf
    groups: list[list[tuple[float, float]]] = [[] for _ in targets]
    for press_uv, press_xy in zip(uv, xy, strict=True):
        d = np.hypot(*(targets - press_xy).T)
        i = int(np.argmin(d))
        if d[i] <= radius_mm:
            groups[i].append(press_uv)
    missing = [i for i, g in enumerate(groups) if not g]
    if missing:
        names = ", ".join(f"{i + 1} (x {targets[i][0]:+.1f}, y {targets[i][1]:+.1f} mm)"
                          for i in missing)
        raise UserError(
            f"found {len(uv)} presses held >= {min_hold_s} s, but none at point(s) {names} "
            f"of {len(targets)}: press each marked point and hold it still")
    return [tuple(np.median(np.asarray(g), axis=0)) for g in groups]


def fit_from_presses(
    source: FrameSource,
    camera,
    config: StationConfig,
    targets: np.ndarray,
    min_hold_s: float,
    total: int | None = None,
):
    """Track the presses in ``source`` and fit the homography to ``targets`` (in order)."""
    import numpy as np

    from fydpad.progress import progress
    from vision.calibration import CalibrationError, homography_from_presses, press_centroids
    from vision.contact import ContactTracker
    from vision.sources import CameraSource, SourceError

    tracker = ContactTracker(roi_px=camera.roi_px, workspace_mm=camera.workspace_mm,
                             image_flip=camera.image_flip, method=config.tracker.method,
                             robust=config.tracker.robust)
    t, c, u, v, x, y = [], [], [], [], [], []
    frame_size = None
    try:
        for frame in progress(source.frames(), total=total, desc="presses"):
            frame_size = (frame.image.shape[1], frame.image.shape[0])
            contact = tracker.process(frame.image)
            t.append(frame.t_s)
            c.append(contact is not None)
            u.append(np.nan if contact is None else contact.u_px)
            v.append(np.nan if contact is None else contact.v_px)
            x.append(np.nan if contact is None else contact.x_mm)
            y.append(np.nan if contact is None else contact.y_mm)
            # Live: stop once every point has been pressed and the finger has lifted.
            if isinstance(source, CameraSource) and not c[-1] and len(
                press_centroids(t, c, u, v, min_hold_s)
            ) >= len(targets):
                break
    except SourceError as exc:
        raise UserError(str(exc)) from None
    finally:
        source.close()
    presses = match_presses(t, c, u, v, x, y, targets, min_hold_s)
    try:
        return homography_from_presses(presses, targets, camera.image_flip, frame_size,
                                       camera.intrinsics)
    except CalibrationError as exc:
        raise UserError(str(exc)) from None
