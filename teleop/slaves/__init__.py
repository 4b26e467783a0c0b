"""Robot arms the slave loop drives, behind one Protocol (docs/architecture.md).

Every arm takes positions in its base frame in millimetres; the attitude is fixed with
the tool perpendicular to the surface (paper IV-B).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from vision.errors import DeviceFault


class ArmFault(DeviceFault, RuntimeError):
    """The arm cannot follow (protective stop, lost connection): the message says what to check."""

    device = "robot arm"
    check = "the robot's connection and whether it is in a protective stop"


@runtime_checkable
class Arm(Protocol):
    """A position-controlled arm. ``servo`` is called once per slave tick."""

    name: str
    lag_s: float  # typical lag of the actual position behind the command (feed-forward)

    def start(self, home_mm: np.ndarray) -> None:
        """Connect and bring the tool to ``home_mm`` (base frame)."""

    def servo(self, target_mm: np.ndarray, now_s: float) -> None:
        """Stream one position target; raise ArmFault if the arm stopped following."""

    def actual_mm(self) -> np.ndarray:
        """Measured tool position, base frame."""

    def hold(self) -> None:
        """Stay still where the arm is now."""

    def close(self) -> None:
        """Stop and disconnect; safe to call twice."""
