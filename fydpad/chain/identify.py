"""Identification (Felicetti 2022 section 3.2): excite the chain with band-limited noise at
each stiffness setting and a fixed normal force, estimate TF = CPSD_yx / PSD_x with
Welch averaging, refuse what cannot be trusted, collect a :class:`TfSet`."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fydpad.accel.sim import FULL_SCALE_M_S2
from fydpad.chain import ChainError
from fydpad.chain.estimate import check_coherence, check_response, welch_tf
from fydpad.chain.excitation import band_noise, check_band
from fydpad.chain.measure import check_force, drive_signal
from fydpad.chain.tf_file import TfEntry

#: Peak of the excitation, as a share of eq. 3's vibration headroom.
LEVEL = 0.8


def accel_limits(accel) -> tuple[float, float | None]:
    """(LSB, full scale) of an accelerometer backend, m/s^2, where it declares them."""
    lsb = float(getattr(accel, "lsb_m_s2", 0.0) or 0.0)
    full = getattr(accel, "full_scale_m_s2", None)
    if full is None and type(accel).__name__ == "SimAccelerometer":
        full = FULL_SCALE_M_S2
    return lsb, full


def identify_entry(
    session, stiffness_n_per_mm: float, seconds: float, band_hz: tuple[float, float],
    level: float = LEVEL, seed: int = 0, nperseg: int = 512, force_n: float = 0.3,
    force_tolerance_n: float = 0.1, axis: str = "x",
    progress: Callable[[int], None] | None = None,
) -> TfEntry:
    """One stiffness setting: hold it, excite, check, estimate."""
    what = f"stiffness {stiffness_n_per_mm:g} N/mm"
    rate_hz = session.rate_hz
    band_hz = check_band(band_hz, rate_hz)
    if not 0.0 < level <= 1.0:
        raise ChainError(f"--level {level:g}: must be in (0, 1] (share of the headroom)")
    n = round(seconds * rate_hz)
    if n < 8 * nperseg:
        raise ChainError(f"--seconds {seconds:g}: too short for Welch averaging; give at "
                         f"least {8 * nperseg / rate_hz:g} s")
    theta = session.hold(stiffness_n_per_mm, force_n)
    peak = level * session.drive.composer.vibration_limit
    x = band_noise(n, rate_hz, band_hz, peak, seed)
    run = drive_signal(session.drive, session.accel, x, session.clock, axis,
                       pace=session.pacer(), force=session.force, progress=progress,
                       what=what)
    if run.vibration_clips:
        raise ChainError(f"{what}: the excitation clipped eq. 3 {run.vibration_clips} times; "
                         "lower --level")
    lsb, full = accel_limits(session.accel)
    check_response(run.y_m_s2, lsb, full, what)
    est = welch_tf(run.x_duty, run.y_m_s2, rate_hz, nperseg)
    check_coherence(est, band_hz, what)
    f_mean, f_sd = check_force(run.force_n, force_n, force_tolerance_n, what)
    return TfEntry(float(stiffness_n_per_mm), float(theta), f_mean, f_sd, est)


def nominal_peak(est, band_hz) -> float:
    """The frequency of |TF|'s largest value over the coherent band (the resonance)."""
    good = est.coherent(band_hz)
    return float(est.freqs_hz[good][np.argmax(np.abs(est.tf[good]))])
