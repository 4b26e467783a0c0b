"""Workspace frame (mm, seen from above) <-> robot base frame (mm), paper IV-B.

robot = origin + R_rpy @ (scale * [s*x, y, 0] + [0, 0, -z_scale * indentation]),
s = -1 with ``reflect_x``. The end effector's attitude stays fixed, perpendicular to
the surface (the paper's choice): its tool axis points along -R_rpy[:, 2].
"""

from __future__ import annotations

import math

import numpy as np

from teleop.config import MappingConfig


def rpy_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg))
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


class Mapping:
    """Affine map between the two frames, built from a MappingConfig."""

    def __init__(self, cfg: MappingConfig) -> None:
        if cfg.scale <= 0 or cfg.z_scale <= 0:
            raise ValueError(f"mapping scale and z_scale must be > 0, got {cfg.scale}, "
                             f"{cfg.z_scale}")
        self.origin_mm = np.asarray(cfg.origin_mm, float)
        self.rotation = rpy_matrix(*cfg.rpy_deg)
        # Workspace vector (x, y, indentation) -> surface-frame vector (z up).
        self._lin = np.diag([(-1.0 if cfg.reflect_x else 1.0) * cfg.scale, cfg.scale,
                             -cfg.z_scale])
        self._fwd = self.rotation @ self._lin
        self._inv = np.linalg.inv(self._fwd)

    def to_robot(self, ws_mm: np.ndarray) -> np.ndarray:
        """Workspace (x, y, indentation) mm -> robot base frame mm."""
        return self.origin_mm + self._fwd @ np.asarray(ws_mm, float)

    def to_workspace(self, robot_mm: np.ndarray) -> np.ndarray:
        """Robot base frame mm -> workspace (x, y, indentation) mm."""
        return self._inv @ (np.asarray(robot_mm, float) - self.origin_mm)

    def tool_down(self) -> np.ndarray:
        """Unit vector of the tool axis in the base frame: into the surface."""
        return -self.rotation[:, 2]
