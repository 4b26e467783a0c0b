"""Compensation check (Felicetti 2022 section 4.1, Fig. 8): play a target through the chain
uncompensated and compensated, and compare the spectra the fabric reproduces.

Uncompensated means a gain-only calibration: the target divided by the chain's typical
gain (median |TF| over the coherent band), i.e. what the station does without a TF.
Compensated: the live minimum-phase FIR inverse (and, for reference, the offline FFT
form of eqs. 2-4). The target is scaled (one factor for all) so that no drive exceeds
``level`` of eq. 3's vibration headroom; its spectrum is then compared absolutely, in
m/s^2, with the reproduced one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from fydpad.chain import ChainError
from fydpad.chain.compensate import compensate_offline, reference_gain
from fydpad.chain.estimate import check_response
from fydpad.chain.excitation import band_noise
from fydpad.chain.identify import LEVEL, accel_limits
from fydpad.chain.inverse_filter import fir_filter
from fydpad.chain.live import NTAPS, design_inverse
from fydpad.chain.measure import drive_signal
from fydpad.chain.tf_file import TfEntry

Array = NDArray[np.float64]

#: Bins more than this below the target's PSD peak are left out of the comparison: the
#: accelerometer's floor (3.9 mg LSB) is there, not the chain.
DYNAMIC_RANGE_DB = 25.0


@dataclass(frozen=True)
class CheckResult:
    freqs_hz: Array
    target_psd: Array
    uncompensated_psd: Array
    compensated_psd: Array
    offline_psd: Array | None
    #: Bins compared: coherent in the TF and within DYNAMIC_RANGE_DB of the target peak.
    compared: NDArray[np.bool_]
    resonance_hz: float
    figures: dict


def band_target(n: int, rate_hz: float, band_hz: tuple[float, float], seed: int = 0) -> Array:
    """A test target: band-limited noise with a 6 dB bump at 60-150 Hz (a texture-like
    shape, not flat, so the check sees the chain reshape it)."""
    x = band_noise(n, rate_hz, band_hz, 1.0, seed)
    sos = signal.butter(2, (60.0, 150.0), "bandpass", fs=rate_hz, output="sos")
    return x + signal.sosfilt(sos, x)


def scan_target(texture: str, speed_mm_s: float, seconds: float, rate_hz: float,
                seed: int = 0) -> Array:
    """A texture's vibration as the pad's scans record it (``fydpad texture
    generate-scans``: DFT321 of the 3 axes, 10 Hz high-pass), at ``rate_hz``."""
    # lazy: the scan generator and the texture library load only for a texture target
    from fydpad.synth.texture_scans import TEXTURES, generate_scan
    from fydpad.texture.lpc.dft321 import preprocess

    if texture not in TEXTURES:
        raise ChainError(f"--target scan:{texture}: unknown texture; one of "
                         f"{', '.join(TEXTURES)}")
    scan = generate_scan(texture, speed_mm_s, seconds, seed=seed, fs_hz=rate_hz)
    return preprocess(scan.acc, rate_hz)


def _psd(x: Array, rate_hz: float, nperseg: int) -> tuple[Array, Array]:
    return signal.welch(x, rate_hz, nperseg=nperseg)


def check_compensation(session, entry: TfEntry, band_hz: tuple[float, float],
                       target: Array, level: float = LEVEL, ntaps: int = NTAPS,
                       nperseg: int = 512, offline: bool = True, axis: str = "x",
                       force_n: float = 0.3, progress=None) -> CheckResult:
    """Reproduce ``target`` (m/s^2, at the chain's rate) three ways; spectra and figures."""
    rate_hz = session.rate_hz
    est = entry.estimate
    ref = reference_gain(est, band_hz)
    h = design_inverse(est, rate_hz, band_hz, ntaps)
    comp, _ = fir_filter(h, target)
    drives = {"uncompensated": np.asarray(target) / ref, "compensated": comp}
    if offline:
        drives["offline"] = compensate_offline(target, rate_hz, est, band_hz)
    peak = max(float(np.max(np.abs(d))) for d in drives.values())
    if not peak > 0:
        raise ChainError("the target signal is all zeros")
    scale = level * session.drive.composer.vibration_limit / peak
    target = np.asarray(target) * scale
    session.hold(entry.stiffness_n_per_mm, force_n)
    lsb, full = accel_limits(session.accel)
    f, pt = _psd(target, rate_hz, nperseg)
    psd: dict[str, Array] = {}
    clips = 0
    for name, d in drives.items():
        run = drive_signal(session.drive, session.accel, d * scale, session.clock, axis,
                           pace=session.pacer(), progress=progress, what=f"check {name}")
        check_response(run.y_m_s2, lsb, full, f"check {name}")
        clips += run.vibration_clips
        psd[name] = _psd(run.y_m_s2, rate_hz, nperseg)[1]
    good = est.coherent(band_hz) if est.freqs_hz.size == f.size else _coherent_on(est, f,
                                                                                  band_hz)
    compared = good & (pt >= pt[good].max() * 10 ** (-DYNAMIC_RANGE_DB / 10))
    res = f[good][np.argmax(np.abs(np.interp(f[good], est.freqs_hz, np.abs(est.tf))))]
    i_res = int(np.argmin(np.abs(f - res)))

    def err_db(p: Array) -> Array:
        return 10 * np.log10(p[compared] / pt[compared])

    figures = {
        "stiffness_n_per_mm": entry.stiffness_n_per_mm,
        "resonance_hz": float(res),
        "compared_bins": int(compared.sum()),
        "compared_hz": [float(f[compared].min()), float(f[compared].max())],
        "compensated_max_error_db": float(np.max(np.abs(err_db(psd["compensated"])))),
        "uncompensated_max_error_db": float(np.max(np.abs(err_db(psd["uncompensated"])))),
        "uncompensated_error_at_resonance_db":
            float(10 * np.log10(psd["uncompensated"][i_res] / pt[i_res])),
        "compensated_error_at_resonance_db":
            float(10 * np.log10(psd["compensated"][i_res] / pt[i_res])),
        "vibration_clips": clips,
        "target_scale": float(scale),
    }
    if offline:
        figures["offline_max_error_db"] = float(np.max(np.abs(err_db(psd["offline"]))))
    return CheckResult(f, pt, psd["uncompensated"], psd["compensated"], psd.get("offline"),
                       compared, float(res), figures)


def _coherent_on(est, f: Array, band_hz) -> NDArray[np.bool_]:
    coh = np.interp(f, est.freqs_hz, est.coherence)
    return (f >= band_hz[0]) & (f <= band_hz[1]) & (coh > 0.9)
