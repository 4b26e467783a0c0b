"""The finger state: the one stream type every consumer reads (docs/architecture.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class FingerState:
    """What the pad knows about the finger at one instant, in the workspace frame.

    Units are in the names. Quantities that are unknown at this instant (no contact,
    no IR sensors, no load cell) are NaN, so a state is always a flat record of floats.
    """

    t_s: float
    contact: bool
    x_mm: float = math.nan
    y_mm: float = math.nan
    indentation_mm: float = math.nan
    speed_mm_s: float = math.nan
    force_n: float = math.nan

    @classmethod
    def no_contact(cls, t_s: float, force_n: float = math.nan) -> FingerState:
        """A state without a finger on the fabric: indentation 0, position unknown."""
        return cls(t_s=t_s, contact=False, indentation_mm=0.0, speed_mm_s=0.0, force_n=force_n)
