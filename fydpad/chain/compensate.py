"""Pre-compensation by the identified TF (Felicetti 2022 section 3.3): Z = FIV / TF (eq. 3),
z = IFFT(Z) (eq. 4), so that W = Z TF = FIV (eq. 5), regularised.

The plain ratio blows up where |TF| is small or where TF was not measured well, so:

- **Tikhonov** on the bins where the coherence exceeds ``coh_min``:
  ``inv = conj(TF) / (|TF|^2 + (eps * ref)^2)`` with ``ref`` the median |TF| there;
  where |TF| >> eps ref it is 1/TF, and it never boosts beyond ``1 / (2 eps ref)``
  (``EPS`` = 0.05: at most +20 dB over the chain's typical gain);
- **no boost elsewhere**: on the other bins (below, above or in holes of the coherent
  band) the log-magnitude and the unwrapped phase are interpolated between coherent
  bins and held flat beyond the first and last one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fydpad.chain import ChainError
from fydpad.chain.estimate import COHERENCE_MIN, TfEstimate

Array = NDArray[np.float64]

#: Default Tikhonov weight, relative to the chain's median in-band gain.
EPS = 0.05


def reference_gain(est: TfEstimate, band_hz: tuple[float, float],
                   coh_min: float = COHERENCE_MIN) -> float:
    """The chain's typical gain: median |TF| over the coherent band (what a gain-only
    calibration, i.e. no compensation, would use)."""
    good = est.coherent(band_hz, coh_min)
    if not good.any():
        raise ChainError(f"no bin of {band_hz[0]:g}-{band_hz[1]:g} Hz has coherence above "
                         f"{coh_min:g}: identify the chain again")
    return float(np.median(np.abs(est.tf[good])))


def regularised_inverse(est: TfEstimate, band_hz: tuple[float, float], eps: float = EPS,
                        coh_min: float = COHERENCE_MIN) -> NDArray[np.complex128]:
    """1/TF on ``est.freqs_hz``, Tikhonov-regularised, no boost outside the coherent
    bins (module docstring). Units: input per output (duty per m/s^2)."""
    good = est.coherent(band_hz, coh_min)
    ref = reference_gain(est, band_hz, coh_min)
    tf = est.tf[good]
    inv = np.conj(tf) / (np.abs(tf) ** 2 + (eps * ref) ** 2)
    return resample_response(est.freqs_hz[good], inv, est.freqs_hz)


def resample_response(freqs_hz: Array, response: NDArray[np.complex128],
                      to_freqs_hz: Array) -> NDArray[np.complex128]:
    """A complex response on another frequency grid (log-magnitude and unwrapped phase
    interpolated, held beyond the ends)."""
    logmag = np.interp(to_freqs_hz, freqs_hz, np.log(np.maximum(np.abs(response), 1e-300)))
    phase = np.interp(to_freqs_hz, freqs_hz, np.unwrap(np.angle(response)))
    return np.exp(logmag + 1j * phase)


def compensate_offline(target: Array, rate_hz: float, est: TfEstimate,
                       band_hz: tuple[float, float], eps: float = EPS,
                       coh_min: float = COHERENCE_MIN) -> Array:
    """z(t) for a whole target signal (eqs. 2-4): FFT, times the regularised inverse,
    IFFT. The FFT treats the signal as periodic, as the paper's processing does, so a
    target that does not fade in and out rings at its ends."""
    target = np.asarray(target, np.float64)
    n = target.size
    inv = regularised_inverse(est, band_hz, eps, coh_min)
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    big_z = np.fft.rfft(target) * resample_response(est.freqs_hz, inv, f)
    return np.fft.irfft(big_z, n)
