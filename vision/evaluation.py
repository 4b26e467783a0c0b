"""Tracking accuracy against ground truth (``truth.csv``), over arrays."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class TrackingScore:
    """How a track compares with the truth, frame by frame."""

    frames: int
    contact_frames: int
    #: Root mean square of the 2-D position error over frames where both say contact.
    rmse_mm: float
    #: Largest 2-D position error over those frames.
    max_error_mm: float
    #: Frames with a true contact that the tracker did not report.
    missed: int
    #: Frames the tracker reported a contact that is not there.
    false: int
    #: Frames left out of ``missed`` and ``false`` because the finger touched down or
    #: lifted off during their exposure (either answer is right), and of those, how many
    #: the tracker answered differently from the truth at mid-exposure.
    straddling: int = 0
    straddling_disagree: int = 0

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def score_tracking(
    contact: ArrayLike,
    x_mm: ArrayLike,
    y_mm: ArrayLike,
    true_contact: ArrayLike,
    true_x_mm: ArrayLike,
    true_y_mm: ArrayLike,
    straddling: ArrayLike | None = None,
) -> TrackingScore:
    """Compare tracked contacts and centroids with the truth, frame by frame.

    ``straddling`` (optional, per frame): the finger touched down or lifted off during
    the frame's exposure; such frames count in the position error where both say
    contact, but not as missed or false."""
    c = np.asarray(contact, dtype=bool)
    tc = np.asarray(true_contact, dtype=bool)
    if c.shape != tc.shape:
        raise ValueError(f"track has {c.size} frames, truth has {tc.size}")
    amb = np.zeros(c.shape, bool) if straddling is None else np.asarray(straddling, bool)
    if amb.shape != c.shape:
        raise ValueError(f"straddling has {amb.size} frames, truth has {tc.size}")
    both = c & tc
    err = np.hypot(
        np.asarray(x_mm, dtype=float)[both] - np.asarray(true_x_mm, dtype=float)[both],
        np.asarray(y_mm, dtype=float)[both] - np.asarray(true_y_mm, dtype=float)[both],
    )
    return TrackingScore(
        frames=int(c.size),
        contact_frames=int(tc.sum()),
        rmse_mm=float(np.sqrt(np.mean(err**2))) if err.size else float("nan"),
        max_error_mm=float(err.max()) if err.size else float("nan"),
        missed=int(np.count_nonzero(tc & ~c & ~amb)),
        false=int(np.count_nonzero(c & ~tc & ~amb)),
        straddling=int(np.count_nonzero(amb)),
        straddling_disagree=int(np.count_nonzero(amb & (c != tc))),
    )
