"""Camera and workspace calibration: lens intrinsics from ChArUco views, and the
image-to-workspace homography from presses at known points.

Pixel coordinates here are the project's continuous ones (pixel i covers [i, i+1));
OpenCV puts pixel centres at integers, so points are shifted by half a pixel on the way
in and out of OpenCV.

The chain from a tracked contact to the workspace, when calibrated:
flipped-frame point -> raw-frame point (undo the flip) -> undistorted raw point (lens
intrinsics) -> workspace mm (homography, which also absorbs the flip, the camera's tilt
and its height).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.errors import UserError
from vision.mapping import flip_point


class CalibrationError(UserError, ValueError):
    """Calibration data is too little, degenerate or inconsistent; the message says which."""


@dataclass
class CameraIntrinsics:
    """Pinhole camera matrix and lens distortion (OpenCV's k1, k2, p1, p2, k3) of raw frames."""

    camera_matrix: tuple[float, ...]  # 9 values, row-major 3x3
    dist_coeffs: tuple[float, ...]  # 5 values
    frame_size: tuple[int, int]
    rms_px: float = 0.0

    @property
    def k(self) -> NDArray[np.float64]:
        return np.asarray(self.camera_matrix, np.float64).reshape(3, 3)

    @property
    def dist(self) -> NDArray[np.float64]:
        return np.asarray(self.dist_coeffs, np.float64)


@dataclass
class CharucoBoardSpec:
    """A ChArUco board: squares across and down, their sizes, the ArUco dictionary."""

    squares_x: int = 7
    squares_y: int = 5
    square_mm: float = 12.0
    marker_mm: float = 9.0
    dictionary: str = "DICT_5X5_100"

    def board(self) -> cv2.aruco.CharucoBoard:
        try:
            dict_id = getattr(cv2.aruco, self.dictionary)
        except AttributeError:
            raise CalibrationError(f"unknown ArUco dictionary {self.dictionary!r}") from None
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_mm, self.marker_mm,
            cv2.aruco.getPredefinedDictionary(dict_id),
        )


def calibrate_charuco(
    images: Iterable[NDArray[np.uint8]],
    spec: CharucoBoardSpec,
    min_corners: int = 8,
    min_views: int = 5,
) -> tuple[CameraIntrinsics, int]:
    """Intrinsics from views of a ChArUco board; returns them and the number of views used."""
    board = spec.board()
    detector = cv2.aruco.CharucoDetector(board)
    obj_points, img_points = [], []
    size: tuple[int, int] | None = None
    for image in images:
        grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        size = (grey.shape[1], grey.shape[0])
        corners, ids, _, _ = detector.detectBoard(grey)
        if ids is None or len(ids) < min_corners:
            continue
        obj, img = board.matchImagePoints(corners, ids)
        obj_points.append(obj.astype(np.float32))
        img_points.append(img.astype(np.float32))
    if size is None:
        raise CalibrationError("no images to calibrate from")
    if len(obj_points) < min_views:
        raise CalibrationError(
            f"the board was found in {len(obj_points)} views with >= {min_corners} corners; "
            f"at least {min_views} are needed (check the board's size, dictionary and lighting, "
            "and tilt it across the whole view)"
        )
    rms, k, dist, _, _ = cv2.calibrateCamera(obj_points, img_points, size, None, None)
    return (
        CameraIntrinsics(
            camera_matrix=tuple(float(v) for v in k.ravel()),
            dist_coeffs=tuple(float(v) for v in dist.ravel()[:5]),
            frame_size=size,
            rms_px=float(rms),
        ),
        len(obj_points),
    )


def undistort_points(uv_px: ArrayLike, intrinsics: CameraIntrinsics) -> NDArray[np.float64]:
    """Raw-frame points (continuous pixels, shape (n, 2)) to where a distortion-free camera
    with the same camera matrix would see them."""
    pts = np.asarray(uv_px, np.float64).reshape(-1, 1, 2) - 0.5
    k = intrinsics.k
    out = cv2.undistortPoints(pts, k, intrinsics.dist, P=k)
    return out.reshape(-1, 2) + 0.5


def default_targets_mm(workspace_mm: tuple[float, float], n: int = 9) -> NDArray[np.float64]:
    """The marked points the user presses: a square grid (3x3 by default) over 80 % of the
    workspace, in reading order as seen from above (far row first, left to right)."""
    side = round(np.sqrt(n))
    if side * side != n or side < 2:
        raise CalibrationError(f"the number of points must be a square >= 4, got {n}")
    xs = np.linspace(-0.4, 0.4, side) * workspace_mm[0]
    ys = np.linspace(0.4, -0.4, side) * workspace_mm[1]
    return np.array([(x, y) for y in ys for x in xs])


@dataclass
class WorkspaceHomography:
    """Undistorted raw-frame pixels -> workspace mm (3x3, row-major) and its fit residual."""

    matrix: tuple[float, ...]  # 9 values
    rms_mm: float = 0.0

    @property
    def h(self) -> NDArray[np.float64]:
        return np.asarray(self.matrix, np.float64).reshape(3, 3)


def fit_workspace_homography(
    raw_points_px: ArrayLike, workspace_points_mm: ArrayLike
) -> WorkspaceHomography:
    """Least-squares homography from (undistorted, raw-frame) pixels to workspace mm."""
    src = np.asarray(raw_points_px, np.float64).reshape(-1, 2)
    dst = np.asarray(workspace_points_mm, np.float64).reshape(-1, 2)
    if src.shape != dst.shape:
        raise CalibrationError(f"{len(src)} image points but {len(dst)} workspace points")
    if len(src) < 4:
        raise CalibrationError(f"a homography needs at least 4 points, got {len(src)}")
    for name, pts in (("workspace", dst), ("image", src)):
        centred = pts - pts.mean(axis=0)
        s = np.linalg.svd(centred, compute_uv=False)
        if s[1] < 1e-3 * max(s[0], 1e-12):
            raise CalibrationError(f"the {name} points are collinear: press points spread in 2-D")
    h, _ = cv2.findHomography(src, dst, 0)
    if h is None:
        raise CalibrationError("no homography fits these points (are they degenerate?)")
    fitted = apply_homography(h, src)
    rms = float(np.sqrt(np.mean(np.sum((fitted - dst) ** 2, axis=1))))
    return WorkspaceHomography(matrix=tuple(float(v) for v in h.ravel()), rms_mm=rms)


def apply_homography(h: ArrayLike, pts: ArrayLike) -> NDArray[np.float64]:
    h = np.asarray(h, np.float64)
    p = np.asarray(pts, np.float64).reshape(-1, 2)
    q = p @ h[:2, :2].T + h[:2, 2]
    w = p @ h[2, :2] + h[2, 2]
    return q / w[:, None]


class CalibratedMapping:
    """Flipped-frame contact points to workspace mm through the calibration chain."""

    def __init__(
        self,
        homography: WorkspaceHomography,
        intrinsics: CameraIntrinsics | None,
        image_flip: str,
    ):
        self.homography = homography
        self.intrinsics = intrinsics
        self.image_flip = image_flip
        self._h = homography.h

    def to_workspace(
        self, u_px: float, v_px: float, frame_size: tuple[int, int]
    ) -> tuple[float, float]:
        raw = raw_undistorted_point(u_px, v_px, self.image_flip, frame_size, self.intrinsics)
        x, y = apply_homography(self._h, raw)[0]
        return float(x), float(y)


def raw_undistorted_point(
    u_px: float,
    v_px: float,
    image_flip: str,
    frame_size: tuple[int, int],
    intrinsics: CameraIntrinsics | None,
) -> NDArray[np.float64]:
    """A flipped-frame point as the homography takes it: raw frame, lens undone (1x2)."""
    u, v = flip_point(u_px, v_px, image_flip, frame_size)
    p = np.array([[u, v]], np.float64)
    return undistort_points(p, intrinsics) if intrinsics is not None else p


def press_centroids(
    t_s: Sequence[float] | NDArray,
    contact: Sequence[bool] | NDArray,
    u_px: Sequence[float] | NDArray,
    v_px: Sequence[float] | NDArray,
    min_hold_s: float = 0.4,
) -> list[tuple[float, float]]:
    """The median position of each press held at least ``min_hold_s``, in order.

    The first and last fifth of each press are left out: the finger is still landing
    or lifting there.
    """
    t = np.asarray(t_s, float)
    c = np.asarray(contact, bool)
    u = np.asarray(u_px, float)
    v = np.asarray(v_px, float)
    edges = np.flatnonzero(np.diff(np.r_[0, c.astype(int), 0]))
    presses = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if t[stop - 1] - t[start] < min_hold_s:
            continue
        trim = (stop - start) // 5
        sl = slice(start + trim, stop - trim)
        presses.append((float(np.median(u[sl])), float(np.median(v[sl]))))
    return presses


def homography_from_presses(
    presses_px: Sequence[tuple[float, float]],
    targets_mm: ArrayLike,
    image_flip: str,
    frame_size: tuple[int, int],
    intrinsics: CameraIntrinsics | None,
) -> tuple[WorkspaceHomography, NDArray[np.float64]]:
    """The homography from press centroids (flipped-frame pixels, in target order) to the
    marked points, and each point's residual (mm)."""
    targets = np.asarray(targets_mm, np.float64).reshape(-1, 2)
    raw = np.vstack([raw_undistorted_point(u, v, image_flip, frame_size, intrinsics)
                     for u, v in presses_px]) if len(presses_px) else np.empty((0, 2))
    homography = fit_workspace_homography(raw, targets)
    residual = np.hypot(*(apply_homography(homography.h, raw) - targets).T)
    return homography, residual

