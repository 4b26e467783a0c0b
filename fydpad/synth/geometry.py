"""Camera geometry of the synthetic pad: pixel grids in the workspace frame.

Rendering happens in the *flipped* frame (the fabric seen from above, docs/recording_format.md);
the raw camera frame is produced by flipping at the very end. Pixel (col i, row j) has
its centre at (i + 0.5, j + 0.5), mapped linearly through the ROI onto the workspace.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vision.mapping import roi_to_workspace, workspace_to_roi


@dataclass(frozen=True)
class CameraGeometry:
    frame_size: tuple[int, int] = (640, 480)
    roi_px: tuple[int, int, int, int] = (24, 22, 592, 414)
    workspace_mm: tuple[float, float] = (100.0, 70.0)
    #: Workspace x of every pixel column centre, y of every row centre (float32).
    x_cols_mm: NDArray[np.float32] = field(init=False, repr=False, compare=False)
    y_rows_mm: NDArray[np.float32] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        w, h = self.frame_size
        xs, _ = roi_to_workspace(np.arange(w) + 0.5, np.zeros(w), self.roi_px, self.workspace_mm)
        _, ys = roi_to_workspace(np.zeros(h), np.arange(h) + 0.5, self.roi_px, self.workspace_mm)
        object.__setattr__(self, "x_cols_mm", xs.astype(np.float32))
        object.__setattr__(self, "y_rows_mm", ys.astype(np.float32))

    @property
    def px_per_mm(self) -> tuple[float, float]:
        return (self.roi_px[2] / self.workspace_mm[0], self.roi_px[3] / self.workspace_mm[1])

    def to_px(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """Workspace mm -> continuous pixel coordinates of the flipped frame."""
        u, v = workspace_to_roi(x_mm, y_mm, self.roi_px, self.workspace_mm)
        return float(u), float(v)

    def box(self, x_mm: float, y_mm: float, half_w_mm: float, half_h_mm: float
            ) -> tuple[slice, slice]:
        """Row and column slices of the pixels within a box around (x, y) (may be empty)."""
        w, h = self.frame_size
        sx, sy = self.px_per_mm
        u, v = self.to_px(x_mm, y_mm)
        c0 = int(np.clip(np.floor(u - half_w_mm * sx), 0, w))
        c1 = int(np.clip(np.ceil(u + half_w_mm * sx), 0, w))
        r0 = int(np.clip(np.floor(v - half_h_mm * sy), 0, h))
        r1 = int(np.clip(np.ceil(v + half_h_mm * sy), 0, h))
        return slice(r0, r1), slice(c0, c1)

    def grid(self, rows: slice, cols: slice) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Broadcastable (x_mm[1, n], y_mm[m, 1]) of the pixels in a box."""
        return self.x_cols_mm[None, cols], self.y_rows_mm[rows, None]
