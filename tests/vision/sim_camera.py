"""A pinhole camera with lens distortion under the fabric, to render calibration scenes.

Independent of the code under test: it renders by ray casting (every raw pixel's ray
meets a plane, whose texture is sampled there), not by the project's mappings.
World frame = the workspace frame (mm, x to the user's right, y away from the user,
z up, fabric at z = 0). The camera sits below and looks up; its image is mirrored
horizontally (``image_flip = "horizontal"``).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray


def rot_xyz(ax_deg: float, ay_deg: float, az_deg: float) -> NDArray[np.float64]:
    ax, ay, az = np.radians([ax_deg, ay_deg, az_deg])
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


class SimCamera:
    """Wide-angle webcam ~100 mm under the fabric, tilted, with barrel distortion."""

    def __init__(
        self,
        f_px: float = 560.0,
        dist: tuple[float, ...] = (-0.30, 0.10, 0.0015, -0.001, 0.0),
        tilt_deg: tuple[float, float] = (4.0, -3.0),
        height_mm: float = 100.0,
        size: tuple[int, int] = (640, 480),
    ):
        self.size = size
        self.k = np.array([[f_px, 0, size[0] / 2 + 3.0], [0, f_px * 1.01, size[1] / 2 - 4.0],
                           [0, 0, 1]])
        self.dist = np.array(dist, np.float64)
        # Camera axes in the world: looking up (+z); its x along -x (mirrored image).
        base = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]])  # rows: cam axes in world
        self.r = base @ rot_xyz(tilt_deg[0], tilt_deg[1], 0.0)  # world -> camera
        self.centre = np.array([2.0, -1.5, -height_mm])
        self.t = -self.r @ self.centre
        # Ray direction of every raw pixel (continuous centres), in the world frame.
        w, h = size
        uu, vv = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        pix = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2) - 0.5
        norm = cv2.undistortPoints(pix, self.k, self.dist).reshape(-1, 2)
        rays_cam = np.concatenate([norm, np.ones((norm.shape[0], 1))], axis=1)
        self._rays = rays_cam @ self.r  # (R^T d) for each row d

    def project(self, world_mm: NDArray[np.float64]) -> NDArray[np.float64]:
        """World points to raw-frame pixels (continuous coordinates)."""
        rvec, _ = cv2.Rodrigues(self.r)
        pts, _ = cv2.projectPoints(np.asarray(world_mm, np.float64).reshape(-1, 1, 3), rvec,
                                   self.t, self.k, self.dist)
        return pts.reshape(-1, 2) + 0.5

    def plane_coords(
        self, plane_r: NDArray[np.float64] | None = None, plane_t: NDArray[np.float64] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """For each raw pixel: its ray's hit on a plane, in the plane's own (a, b) mm.

        The plane is the fabric (z = 0) unless a pose (plane axes as columns, origin) is given.
        """
        pr = np.eye(3) if plane_r is None else plane_r
        pt = np.zeros(3) if plane_t is None else plane_t
        n = pr[:, 2]
        denom = self._rays @ n
        s = ((pt - self.centre) @ n) / np.where(np.abs(denom) < 1e-9, 1e-9, denom)
        hit = self.centre + s[:, None] * self._rays
        local = (hit - pt) @ pr
        w, h = self.size
        ok = (s > 0).reshape(h, w)
        return local[:, 0].reshape(h, w), local[:, 1].reshape(h, w), ok

    def render_fabric(
        self, shade: Callable[[NDArray, NDArray], NDArray], supersample: int = 1
    ) -> NDArray[np.uint8]:
        """The raw grey frame of the fabric whose brightness at (x_mm, y_mm) is ``shade``."""
        x, y, ok = self.plane_coords()
        img = np.where(ok, shade(x, y), 0.0)
        return np.clip(img, 0, 255).astype(np.uint8)

    def render_board(
        self, board_img: NDArray[np.uint8], px_per_mm: float, pose_r: NDArray, pose_t: NDArray,
    ) -> NDArray[np.uint8]:
        """A raw frame of a printed board (image, top-left at the pose's origin) on grey."""
        a, b, ok = self.plane_coords(pose_r, pose_t)
        map_x = (a * px_per_mm - 0.5).astype(np.float32)
        map_y = (b * px_per_mm - 0.5).astype(np.float32)
        map_x[~ok] = -1
        out = cv2.remap(board_img, map_x, map_y, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=128)
        return out


def press_shade(x0_mm: float, y0_mm: float, radius_mm: float = 4.5) -> Callable:
    """Backlit fabric (bright) with a dark, soft-edged round contact at (x0, y0)."""

    def shade(x: NDArray, y: NDArray) -> NDArray:
        r = np.hypot(x - x0_mm, y - y0_mm)
        edge = np.clip((r - radius_mm) / 1.0 + 0.5, 0.0, 1.0)  # 1 mm soft edge
        return 60.0 + 170.0 * edge

    return shade
