"""Chain compensation in the 1 kHz render loop: per-stiffness minimum-phase inverses of
a TF set, the nearest stiffness selected as the softness request changes.

Normalised (the default for the station): each inverse is scaled by its chain's
typical gain (:func:`fydpad.chain.compensate.reference_gain`), so compensation
reshapes the spectrum (flattens the resonance) while the texture keeps the level that
``vibration_duty_per_unit`` and the per-texture gain give it. Unnormalised, the filter
maps a target acceleration (m/s^2) to duty (``fydpad chain check``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from fydpad.chain.compensate import EPS, reference_gain, regularised_inverse
from fydpad.chain.estimate import COHERENCE_MIN, TfEstimate
from fydpad.chain.inverse_filter import InverseFilter, min_phase_fir
from fydpad.chain.tf_file import TfSet, load_tf_set

#: FIR length: 128 taps at 1 kHz resolve the 10 Hz band edge to within 0.2 dB.
NTAPS = 128


def design_inverse(est: TfEstimate, rate_hz: float, band_hz: tuple[float, float],
                   ntaps: int = NTAPS, eps: float = EPS, coh_min: float = COHERENCE_MIN,
                   normalise: bool = False) -> NDArray[np.float64]:
    """Minimum-phase FIR taps with the regularised inverse's magnitude (duty per m/s^2;
    normalised: times the chain's typical gain, dimensionless)."""
    inv = regularised_inverse(est, band_hz, eps, coh_min)
    h = min_phase_fir(est.freqs_hz, np.abs(inv), rate_hz, ntaps)
    return h * reference_gain(est, band_hz, coh_min) if normalise else h


class LiveCompensator:
    """The render loop's compensation: ``select(k)`` when the stiffness may have changed
    (free when it has not), ``tick(v)`` per sample. Filters are designed here, once."""

    def __init__(self, tfs: TfSet, ntaps: int = NTAPS, normalise: bool = True) -> None:
        self.tfs = tfs
        self._ks = [e.stiffness_n_per_mm for e in tfs.entries]
        self._taps = [design_inverse(e.estimate, tfs.rate_hz, tfs.band_hz, ntaps,
                                     normalise=normalise) for e in tfs.entries]
        self.filter = InverseFilter(self._taps[0])
        self.index = 0
        self._k = math.nan
        self._selected = False
        self.switches = 0

    def select(self, stiffness_n_per_mm: float) -> None:
        k = stiffness_n_per_mm
        if self._selected and (k == self._k or (k != k and self._k != self._k)):
            return
        self._k, self._selected = k, True
        # An index, never entries.index(entry): entries hold arrays, and comparing two
        # equal-looking ones would raise inside the 1 kHz loop.
        i = self.tfs.nearest_index(k)
        if i != self.index:
            self.index = i
            self.filter.set_taps(self._taps[i])  # the input history carries over
            self.switches += 1

    def tick(self, v: float) -> float:
        return self.filter.tick(v)

    def stats(self) -> dict:
        return {"tf_stiffness_n_per_mm": self._ks[self.index], "tf_switches": self.switches}


def open_compensator(path: str, rate_hz: float, channel: str = "vibration") -> LiveCompensator:
    """The compensator of a TF file, checked against the chain's channel and rate."""
    return LiveCompensator(load_tf_set(path, rate_hz, channel))
