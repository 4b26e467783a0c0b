"""Camera (ChArUco) and workspace (homography) calibration on frames rendered through a
known wide-angle lens and a tilted camera (tests/vision/sim_camera.py)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.vision.sim_camera import SimCamera, press_shade, rot_xyz
from vision.calibration import (
    CalibratedMapping,
    CalibrationError,
    CameraIntrinsics,
    CharucoBoardSpec,
    calibrate_charuco,
    default_targets_mm,
    fit_workspace_homography,
    raw_undistorted_point,
    undistort_points,
)
from vision.contact import ContactTracker
from vision.mapping import flip_point

WORKSPACE = (100.0, 70.0)
# As near the workspace's corners as a 9 mm wide press fits inside the view.
CORNERS_MM = np.array([(-44.0, -29.5), (44.0, -29.5), (-44.0, 29.5), (44.0, 29.5)])
#: Corners and edge midpoints: where lens distortion and tilt bend the image most.
BORDER_MM = np.vstack([CORNERS_MM, [(0.0, -29.5), (0.0, 29.5), (-44.0, 0.0), (44.0, 0.0)]])


@pytest.fixture(scope="module")
def cam() -> SimCamera:
    return SimCamera()


def true_intrinsics(cam: SimCamera) -> CameraIntrinsics:
    return CameraIntrinsics(tuple(cam.k.ravel()), tuple(cam.dist), cam.size)


def flipped_roi(cam: SimCamera) -> tuple[int, int, int, int]:
    """The ROI a user would draw: the bounding box of the workspace's border as seen."""
    w, h = WORKSPACE
    s = np.linspace(-0.5, 0.5, 41)
    border = [(a * w, b * h) for a in s for b in (-0.5, 0.5)]
    border += [(a * w, b * h) for a in (-0.5, 0.5) for b in s]
    raw = cam.project(np.array([[x, y, 0.0] for x, y in border]))
    flipped = np.array([flip_point(u, v, "horizontal", cam.size) for u, v in raw])
    x0, y0 = np.floor(flipped.min(axis=0)).astype(int)
    x1, y1 = np.ceil(flipped.max(axis=0)).astype(int)
    return int(x0), int(y0), int(x1 - x0), int(y1 - y0)


def tracked_points(cam: SimCamera, tracker: ContactTracker, points_mm) -> list:
    bare = cam.render_fabric(lambda x, y: np.full_like(x, 230.0))
    out = []
    for x, y in points_mm:
        tracker.reset()
        tracker.process(bare)
        c = tracker.process(cam.render_fabric(press_shade(x, y)))
        assert c is not None, f"no contact found for a press at ({x}, {y}) mm"
        out.append(c)
    return out


SPEC = CharucoBoardSpec(squares_x=7, squares_y=5, square_mm=12.0, marker_mm=9.0)


@pytest.fixture(scope="module")
def charuco_intrinsics(cam: SimCamera) -> tuple[CameraIntrinsics, int]:
    return calibrate_charuco(board_views(cam, SPEC, 14), SPEC)


def test_workspace_homography_beats_the_linear_mapping_at_the_corners(
    cam: SimCamera, charuco_intrinsics
):
    """The whole chain: lens from ChArUco views, then the homography from 9 presses."""
    roi = flipped_roi(cam)
    tracker = ContactTracker(roi_px=roi, workspace_mm=WORKSPACE, image_flip="horizontal")
    targets = default_targets_mm(WORKSPACE)
    assert targets.shape == (9, 2)
    presses = tracked_points(cam, tracker, targets)
    intr = charuco_intrinsics[0]
    mapping = CalibratedMapping(
        fit_workspace_homography(
            np.vstack([raw_undistorted_point(c.u_px, c.v_px, "horizontal", cam.size, intr)
                       for c in presses]),
            targets),
        intr, "horizontal")
    border_contacts = tracked_points(cam, tracker, BORDER_MM)
    linear_err = [np.hypot(c.x_mm - x, c.y_mm - y)
                  for c, (x, y) in zip(border_contacts, BORDER_MM, strict=True)]
    calib_err = []
    for c, (x, y) in zip(border_contacts, BORDER_MM, strict=True):
        xm, ym = mapping.to_workspace(c.u_px, c.v_px, cam.size)
        calib_err.append(np.hypot(xm - x, ym - y))
    print("linear mapping error at the border [mm]:", np.round(linear_err, 2))
    print("calibrated error at the border [mm]:", np.round(calib_err, 3))
    # At the corners the linear ROI mapping is off by millimetres.
    assert min(linear_err[:4]) > 1.0, linear_err
    assert max(calib_err) < 0.3, calib_err


def test_tracker_uses_the_calibration(cam: SimCamera):
    roi = flipped_roi(cam)
    intr = true_intrinsics(cam)
    targets = default_targets_mm(WORKSPACE)
    plain = ContactTracker(roi_px=roi, workspace_mm=WORKSPACE, image_flip="horizontal")
    presses = tracked_points(cam, plain, targets)
    raw = np.vstack([raw_undistorted_point(c.u_px, c.v_px, "horizontal", cam.size, intr)
                     for c in presses])
    calibrated = ContactTracker(
        roi_px=roi, workspace_mm=WORKSPACE, image_flip="horizontal",
        calibration=CalibratedMapping(fit_workspace_homography(raw, targets), intr, "horizontal"),
    )
    (c,) = tracked_points(cam, calibrated, [(-44.0, 29.5)])
    assert np.hypot(c.x_mm + 44.0, c.y_mm - 29.5) < 0.3


def board_views(cam: SimCamera, spec: CharucoBoardSpec, n: int, seed: int = 1):
    board = spec.board()
    px_per_mm = 8.0
    w_mm, h_mm = spec.squares_x * spec.square_mm, spec.squares_y * spec.square_mm
    img = board.generateImage((int(w_mm * px_per_mm), int(h_mm * px_per_mm)), marginSize=0)
    rng = np.random.default_rng(seed)
    views = []
    for _ in range(n):
        # The board held a little below the fabric, tilted up to 35 degrees, spread over the view.
        r = rot_xyz(*rng.uniform(-35, 35, 2), rng.uniform(-30, 30))
        centre = np.array([rng.uniform(-25, 25), rng.uniform(-18, 18), rng.uniform(-10, 0)])
        t = centre - r @ np.array([w_mm / 2, h_mm / 2, 0.0])
        views.append(cam.render_board(img, px_per_mm, r, t))
    return views


def test_charuco_recovers_the_lens(cam: SimCamera, charuco_intrinsics):
    intr, used = charuco_intrinsics
    assert used >= 10
    assert intr.rms_px < 0.5
    # Undistortion by the fitted model agrees with the true one over the workspace.
    grid = np.stack(np.meshgrid(np.linspace(-50, 50, 11), np.linspace(-35, 35, 8)), -1)
    pts = cam.project(np.c_[grid.reshape(-1, 2), np.zeros(grid.size // 2)])
    truth = undistort_points(pts, true_intrinsics(cam))
    fitted = undistort_points(pts, intr)
    # Compare in the workspace: the homography absorbs a different camera matrix, so map
    # both through homographies fitted on the same 9 targets.
    targets = default_targets_mm(WORKSPACE)
    raw_targets = cam.project(np.c_[targets, np.zeros(9)])
    h_true = fit_workspace_homography(undistort_points(raw_targets, true_intrinsics(cam)), targets)
    h_fit = fit_workspace_homography(undistort_points(raw_targets, intr), targets)
    from vision.calibration import apply_homography
    err = np.hypot(*(apply_homography(h_true.h, truth) - apply_homography(h_fit.h, fitted)).T)
    assert err.max() < 0.3, err.max()


def test_too_few_board_views_is_a_clear_error(cam: SimCamera):
    spec = CharucoBoardSpec()
    blank = [np.full((480, 640), 200, np.uint8)] * 6
    with pytest.raises(CalibrationError, match="found in 0 views"):
        calibrate_charuco(blank, spec)


@pytest.mark.parametrize(
    ("src", "dst", "message"),
    [
        ([[0, 0], [1, 0], [0, 1]], [[0, 0], [1, 0], [0, 1]], "at least 4 points"),
        ([[0, 0], [1, 1], [2, 2], [3, 3]], [[0, 0], [1, 0], [2, 0], [3, 0]], "collinear"),
        ([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 0], [1, 0], [0, 1]], "3 workspace points"),
    ],
)
def test_degenerate_workspace_points(src, dst, message):
    with pytest.raises(CalibrationError, match=message):
        fit_workspace_homography(src, dst)


def test_default_targets_need_a_square_count():
    with pytest.raises(CalibrationError):
        default_targets_mm(WORKSPACE, 7)
    t = default_targets_mm(WORKSPACE, 16)
    assert t.shape == (16, 2) and t[:, 0].max() == pytest.approx(40.0)


def test_cv2_has_aruco():
    assert hasattr(cv2, "aruco")  # opencv-contrib is the dependency, not plain opencv
