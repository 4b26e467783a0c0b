"""The LPC renderer (Bianchi 2015 eq. 5, Fig. 9; docs/texture.md, "The render path"):

    a(k) = e(k) + h^T [a(k-1) ... a(k-p)],   e ~ N(0, sigma^2)

with (h, sigma) from a speed table. ``"direct"`` runs eq. 5 itself (the default for the
paper's ``"nearest"`` fits); ``"fir"`` (for ``"stretch"``) runs the same process as its
moving average a(k) = sum_j g_v(j) e(k - j), g_v the impulse response of sigma / A(z) at
the speed (linear between table entries), whose variance is the current filter's whatever
the switching (a gliding direct recursion pumps 2-7x its RMS on a hand's strokes). In it a
line at f = v / lambda made j samples ago rings at the wrong frequency when the speed
changes fast, so lag j takes the filter of the mean speed over it beyond a slack:

    u_j = v(k) + phi_j (d_j - clip(d_j, -slack, slack)),   d_j = mean(v(k-j) .. v(k)) - v(k)

exact for a purely spatial response, unchanged at a constant speed or a hand's wander,
continuous in the speeds; phi_j is 1 over the first half of the lags, then falls linearly
to 0 (the plain tail). ``tick`` (1 kHz, no allocation) and ``block`` (offline) share one
state and one noise stream and give the same samples.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.fft as sfft
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from fydpad.texture.family import hold_finite
from fydpad.texture.lpc.interpolation import build_table
from fydpad.texture.lpc.model_file import TextureModel

Array = NDArray[np.float64]
_NOISE_CHUNK = 4096
_DIRECT_MAX = 48  # an entry used on fewer samples of a block chunk: dot products, not FFT
_HISTORY_MAX_MM_S = 1e4  # the warp's speed history clamp (a mean of 1e306s overflows)
STILL_MM_S = 1.0  # slower is a finger at rest: silence
FIR_MAX = 4096  # longest FIR response (taps)
WARP_LAGS = 512  # lags whose speed is warped; the response's energy is mostly in the first 256
#: A hand's wander stays within it over 0.5 s (dv/dt ~ 10 mm/s^2), a stroke's start does not.
WARP_SLACK_MM_S = 3.0


def lag_fade(lags: int) -> Array:
    """phi_j: 1 over the first half of the lags, then linearly to 0 at the last."""
    half = lags // 2
    return np.concatenate([np.ones(half), np.linspace(1.0, 0.0, lags - half)])


def lag_speeds(recent_mm_s: Array, slack_mm_s: float = WARP_SLACK_MM_S,
               fade: Array | None = None) -> tuple[Array, NDArray[np.bool_]]:
    """u_j (module docstring) from the newest speeds, newest first on the last axis, and
    whether any lag is warped (else the plain FIR applies exactly)."""
    n = recent_mm_s.shape[-1]
    d = np.cumsum(recent_mm_s, axis=-1)
    d *= 1.0 / np.arange(1.0, n + 1.0)
    d -= recent_mm_s[..., :1]
    warped = (d.max(axis=-1) > slack_mm_s) | (d.min(axis=-1) < -slack_mm_s)
    u = d - np.clip(d, -slack_mm_s, slack_mm_s)
    u *= lag_fade(n) if fade is None else fade
    u += recent_mm_s[..., :1]
    return u, warped


def table_position(speed_mm_s: Array, v0_mm_s: float, step_mm_s: float, rows: int
                   ) -> tuple[NDArray[np.int64], Array]:
    """The table's lower entry for each speed and the weight of the upper (clamped)."""
    x = np.clip((speed_mm_s - v0_mm_s) / step_mm_s, 0.0, rows - 1.0)
    k = np.minimum(x.astype(np.int64), rows - 2)
    return k, x - k


def warped_responses(fir: Array, v0_mm_s: float, step_mm_s: float, u_mm_s: Array) -> Array:
    """Each sample's first L taps (..., L) from its lag speeds (..., L): tap j from the
    table ``fir`` (entries x taps) at u_j."""
    k, w = table_position(u_mm_s, v0_mm_s, step_mm_s, fir.shape[0])
    j = np.arange(u_mm_s.shape[-1])
    return (1.0 - w) * fir[k, j] + w * fir[k + 1, j]


class TextureRenderer:
    """Eq. 5 for one texture model (module docstring)."""

    #: At a filter change the direct form's history holds at most this times the new
    #: filter's stationary RMS (switching stable filters pumps energy: 1e60 within 10 s).
    history_cap = 3.0
    #: The cap at a jump of more than one table step (a tracking glitch, a new contact).
    jump_cap = 1.0

    def __init__(
        self, model: TextureModel, *, step_mm_s: float = 0.25, seed: int | None = None,
        ramp_s: float = 0.005, drive_filter: bool = False, structure: str | None = None,
    ):
        """``structure``: "fir" or "direct" (default "fir" for "stretch" models);
        ``drive_filter``: band-pass the output through the model's drive band (order-2
        Butterworth)."""
        self.model = model
        self.fs_hz = float(model.fs_hz)
        self.interpolation = how = model.interpolation
        self.table = t = build_table(model, step_mm_s)
        if not t.stable.all():
            bad = t.speeds_mm_s[~t.stable]
            warnings.warn(
                f"{model.surface}: {bad.size} interpolated filters ({how!r}) are "
                f"unstable ({bad.min():g}-{bad.max():g} mm/s); they are replaced by the "
                "nearest fitted model", stacklevel=2)
            for k in np.flatnonzero(~t.stable):
                j = int(np.argmin(np.abs(model.speeds_mm_s - t.speeds_mm_s[k])))
                t.polys[k] = model.poly(j)
                t.h[k] = model.h[j]
                t.sigma[k] = math.sqrt(model.sigma2[j])
        self.structure = structure or ("fir" if how == "stretch" else "direct")
        if self.structure not in ("direct", "fir"):
            raise ValueError(f"filter structure must be 'direct' or 'fir', not {structure!r}")
        v_min = float(model.speeds_mm_s[0])
        # The slowest model was fitted down to v_min - tolerance: it holds there, then fades.
        self.fade_below_mm_s = max(v_min - model.tolerance_mm_s, 0.5 * v_min)
        self.clamp_above_mm_s = float(model.speeds_mm_s[-1]) + float(model.tolerance_mm_s)
        self.gain = float(model.gain)
        self._alpha = 1.0 - math.exp(-1.0 / (max(ramp_s, 1e-9) * self.fs_hz))
        self._rng = np.random.default_rng(seed)
        self._noise = np.empty(_NOISE_CHUNK)
        self._noise_pos = _NOISE_CHUNK
        self._g = 0.0
        self.clamped = False
        self.warp_slack_mm_s = WARP_SLACK_MM_S  # inf: the plain FIR
        # The per-sample path's rows and history windows: views made once, none per tick.
        self._v0 = float(t.speeds_mm_s[0])
        self._inv_step = 1.0 / float(t.step_mm_s)
        if self.structure == "fir":
            self._init_fir()
        else:
            self.p = p = model.order
            self._buf = np.zeros(2 * p)  # each output written twice: a contiguous window
            self._pos = 0
            self._bwin = [self._buf[k:k + p] for k in range(p)]
            self._sigma = [float(s) for s in t.sigma]
            self._h_rows = list(t.h)
            self._last_i = -1
            # The cap on the history's energy entering each filter (_limit_history).
            rms = np.array([s * np.sqrt(np.mean(1.0 / np.abs(np.fft.rfft(a, 8192)) ** 2))
                            for s, a in zip(t.sigma, t.polys, strict=True)])
            self._cap2 = (self.history_cap * rms) ** 2 * p
            self._cap2_jump = (self.jump_cap * rms) ** 2 * p
        self._sos: Array | None = None
        if drive_filter:
            if model.drive_band_hz is None:
                raise ValueError("drive filter requested but the model has no drive band")
            self._sos = ss.butter(2, model.drive_band_hz, "bandpass", fs=self.fs_hz,
                                  output="sos")
            # The tick's copy in plain floats (NumPy scalars cost ~5 us a tick here).
            self._sos_rows = [tuple(float(c) for c in row) for row in self._sos]
            self._zs = [[0.0, 0.0] for _ in self._sos_rows]

    def _init_fir(self) -> None:
        """The table's responses sigma / A(z) (entries x taps), the FIR state and the tick's
        scratch."""
        # By inverse FFT on 4 FIR_MAX points: a texture model keeps under 1e-4 of its energy
        # past ~2000 samples, so what wraps round is below double precision.
        t, nfft = self.table, 4 * FIR_MAX
        g = np.fft.irfft(t.sigma[:, None] / np.fft.rfft(t.polys, nfft, axis=1), nfft, axis=1)
        g = g[:, :FIR_MAX]
        # Truncated where every entry has less than 1e-4 of its energy left.
        g2 = g**2
        tail = np.cumsum(g2[:, ::-1], axis=1)[:, ::-1] / np.maximum(g2.sum(1, keepdims=True),
                                                                    1e-300)
        n_fir = min(max(int((tail > 1e-4).sum(1).max()), 16), FIR_MAX)
        if g.shape[0] == 1:  # one model: two equal rows keep the interpolation uniform
            g = np.vstack([g, g])
        self.fir = fir = np.ascontiguousarray(g[:, :n_fir])
        self._n_fir_rows, self._n_fir = rows, n_fir = fir.shape
        self._fir_rev = np.ascontiguousarray(fir[:, ::-1])
        # Block path: FFT size (chunks of >= 1024 samples).
        self._nfft = sfft.next_fast_len(n_fir + 1023)
        self._ebuf = np.zeros(2 * n_fir)  # noise, newest first, written twice
        self._epos = 0
        self._lags = lags = min(WARP_LAGS, n_fir)
        self._vbuf = np.zeros(2 * lags)  # the last speeds, newest first, written twice
        self._vpos = 0
        self._v_last = 0.0  # the last finite speed (what a lost track holds)
        self._inv_count = 1.0 / np.arange(1.0, lags + 1.0)
        self._fade = lag_fade(lags)
        self._fade_per_step = self._fade / float(self.table.step_mm_s)
        # A warped tick's scratch: lag deviations, clipped, upper weights, the two taps.
        self._vdev, self._vclip, self._ww, self._g0, self._g1 = np.empty((5, lags))
        self._wk, self._wflat = np.empty((2, lags), np.int64)  # table positions, flat indices
        # Lag-major copy of the first `lags` taps: entry k's tap j at j * rows + k.
        self._fir_lag_major = np.ascontiguousarray(fir[:, :lags].T).ravel()
        self._lag_base = np.arange(lags) * rows
        self._fir_rows = list(fir)
        self._fir_tails = [row[lags:] for row in fir]
        self._ewin = [self._ebuf[k:k + n_fir] for k in range(n_fir)]
        self._ewin_head = [w[:lags] for w in self._ewin]
        self._ewin_tail = [w[lags:] for w in self._ewin]
        self._vwin = [self._vbuf[k:k + lags] for k in range(lags)]

    def reseed(self, seed: int | None) -> None:
        """Restart the noise e(k) from ``seed`` (the pre-drawn chunk dropped)."""
        self._rng = np.random.default_rng(seed)
        self._noise_pos = _NOISE_CHUNK

    def reset(self) -> None:
        """Zero the filter history, the gain and the drive filter."""
        if self.structure == "fir":
            self._ebuf[:] = 0.0
            self._vbuf[:] = 0.0
            self._v_last = 0.0
        else:
            self._buf[:] = 0.0
            self._last_i = -1
        self._g = 0.0
        if self._sos is not None:
            for z in self._zs:
                z[0] = z[1] = 0.0

    def target_gain(self, speed_mm_s: float, contact: bool) -> float:
        """Output gain for this speed: 0 when still or without contact, fade below v_min."""
        if not contact or not speed_mm_s >= STILL_MM_S:
            return 0.0
        if speed_mm_s < self.fade_below_mm_s:
            return self.gain * speed_mm_s / self.fade_below_mm_s
        # Only beyond the fastest model's data is the clamp news (a stroke wanders above it).
        if speed_mm_s > self.clamp_above_mm_s and not self.clamped:
            self.clamped = True
            m = self.model
            warnings.warn(
                f"{m.surface}: speed {speed_mm_s:.1f} mm/s above the fastest model's "
                f"range ({m.speeds_mm_s[-1]:g} mm/s, fitted within {m.tolerance_mm_s:g}): "
                "clamped to it", stacklevel=3)
        return self.gain

    def target_gains(self, v: Array, c: Array) -> Array:
        """:meth:`target_gain` of arrays."""
        on = c & np.isfinite(v) & (v >= STILL_MM_S)  # as tick: no speed, no contact
        g = np.where(on, self.gain * np.minimum(v / self.fade_below_mm_s, 1.0), 0.0)
        fast = on & (v > self.clamp_above_mm_s)
        if fast.any() and not self.clamped:
            self.target_gain(float(v[np.argmax(fast)]), True)
        return g

    def _take_noise(self, n: int) -> Array:
        """The next ``n`` samples of the tick's noise stream."""
        out = np.empty(n)
        k = 0
        while k < n:
            if self._noise_pos >= _NOISE_CHUNK:
                self._rng.standard_normal(out=self._noise)
                self._noise_pos = 0
            m = min(n - k, _NOISE_CHUNK - self._noise_pos)
            out[k:k + m] = self._noise[self._noise_pos:self._noise_pos + m]
            self._noise_pos += m
            k += m
        return out

    def tick(self, speed_mm_s: float, contact: bool = True) -> float:
        """One output sample (m/s^2) for the current speed and contact: eq. 5. A speed that
        is not finite (NaN, inf) is no speed: silence, as a lost track."""
        finite = math.isfinite(speed_mm_s)
        if not finite:
            speed_mm_s, contact = 0.0, False
        if self._noise_pos >= _NOISE_CHUNK:
            self._rng.standard_normal(out=self._noise)
            self._noise_pos = 0
        e = self._noise[self._noise_pos]
        self._noise_pos += 1
        if self.structure == "fir":
            n_fir = self._n_fir
            pos = (self._epos or n_fir) - 1  # the ring's next slot, newest first
            self._ebuf[pos] = e
            self._ebuf[pos + n_fir] = e
            self._epos = pos
            # Each lag's d_j (lag_speeds, the same operations).
            lags = self._lags
            vpos = (self._vpos or lags) - 1
            if finite:
                self._v_last = min(max(speed_mm_s, 0.0), _HISTORY_MAX_MM_S)
            vh = self._v_last
            self._vbuf[vpos] = vh
            self._vbuf[vpos + lags] = vh
            self._vpos = vpos
            d = self._vdev
            np.add.accumulate(self._vwin[vpos], out=d)  # np.cumsum, without its wrapper
            d *= self._inv_count
            d -= vh
            # g_v linear between the two entries around the speed: a stepwise g modulates
            # the output at every step (sandpaper_p80: 10-20 dB too much at 250-500 Hz).
            x = (speed_mm_s - self._v0) * self._inv_step
            x = min(max(x, 0.0), self._n_fir_rows - 1.0) if x == x else 0.0
            k = min(int(x), self._n_fir_rows - 2)
            w = x - k
            slack = self.warp_slack_mm_s
            # argmax/argmin, not max/min: their reductions allocate 1 kB a call here
            if d[d.argmax()] > slack or d[d.argmin()] < -slack:
                # The warped lags' taps, then the plain tail (the fade ends at v).
                y = self._warped_head(d, vh, pos)
                if n_fir > lags:
                    tails, ht = self._fir_tails, self._ewin_tail[pos]
                    y += (1.0 - w) * float(tails[k].dot(ht)) + w * float(tails[k + 1].dot(ht))
            else:
                rows, hist = self._fir_rows, self._ewin[pos]
                y = (1.0 - w) * float(rows[k].dot(hist)) + w * float(rows[k + 1].dot(hist))
        else:
            i = self.table.index(speed_mm_s)
            if i != self._last_i:
                self._limit_history(i)
            p = self.p
            y = self._sigma[i] * e + float(self._h_rows[i].dot(self._bwin[self._pos]))
            pos = (self._pos or p) - 1
            self._buf[pos] = y
            self._buf[pos + p] = y
            self._pos = pos
        self._g += self._alpha * (self.target_gain(speed_mm_s, contact) - self._g)
        out = self._g * y
        if self._sos is not None:
            for (b0, b1, b2, _, a1, a2), z in zip(self._sos_rows, self._zs, strict=True):
                y = b0 * out + z[0]  # transposed direct form II, as scipy's sosfilt
                z[0] = b1 * out - a1 * y + z[1]
                z[1] = b2 * out - a2 * y
                out = y
        return out

    def _warped_head(self, d: Array, speed_mm_s: float, pos: int) -> float:
        """sum_{j < lags} g_{u_j}(j) e(k - j) for the lag deviations ``d``: lag_speeds and
        warped_responses in preallocated buffers."""
        slack = self.warp_slack_mm_s
        # ufuncs, not np.clip: its Python wrapper costs ~2 us a call here
        u = np.maximum(d, -slack, out=self._vclip)
        np.minimum(u, slack, out=u)
        np.subtract(d, u, out=u)
        # The table position (u - v0) / step with the fade folded in (equal up to rounding)
        u *= self._fade_per_step
        u += (speed_mm_s - self._v0) * self._inv_step
        np.maximum(u, 0.0, out=u)
        np.minimum(u, self._n_fir_rows - 1.0, out=u)
        k = self._wk
        np.copyto(k, u, casting="unsafe")  # truncation: u >= 0
        np.minimum(k, self._n_fir_rows - 2, out=k)
        w = np.subtract(u, k, out=self._ww)
        flat = np.add(self._lag_base, k, out=self._wflat)
        # mode="clip": with the default "raise" NumPy copies the output (4 kB a tick);
        # the indices are in range (u clamped to the table above).
        g0 = self._fir_lag_major.take(flat, out=self._g0, mode="clip")
        flat += 1
        g1 = self._fir_lag_major.take(flat, out=self._g1, mode="clip")
        g1 -= g0
        g1 *= w
        g1 += g0
        return float(g1.dot(self._ewin_head[pos]))

    def block(self, speed_mm_s: ArrayLike, contact: ArrayLike = True,
              n: int | None = None) -> Array:
        """``n`` samples (default: the inputs' length) for per-sample or constant speed and
        contact, as ``tick`` gives them."""
        v, c = np.asarray(speed_mm_s, float), np.asarray(contact, bool)
        n = max(v.size, c.size) if n is None else n
        if n == 0:
            return np.zeros(0)
        v, c = np.broadcast_to(v, (n,)), np.broadcast_to(c, (n,))
        t = self.table
        e = self._take_noise(n)
        if self.structure == "fir":
            # A speed that is not finite is no speed (as in tick): the first entry.
            v_ok = np.where(np.isfinite(v), v, self._v0)
            idx, lam = table_position(v_ok, self._v0, t.step_mm_s, self._n_fir_rows)
            # The speed history, as the tick's: not finite holds the last finite speed.
            hv = np.clip(hold_finite(v, self._v_last), 0.0, _HISTORY_MAX_MM_S)
            self._v_last = float(hv[-1])
            y = self._fir_block(e, idx, lam, hv)
        else:
            idx = np.clip(((v - t.speeds_mm_s[0]) / t.step_mm_s + 0.5).astype(np.int64),
                          0, t.h.shape[0] - 1)
            idx[~np.isfinite(v)] = 0
            y = self._direct_block(e, idx)
        target = self.target_gains(v, c)
        g, _zf = ss.lfilter([self._alpha], [1.0, self._alpha - 1.0], target,
                           zi=[(1.0 - self._alpha) * self._g])
        self._g = float(g[-1])
        out = g * y
        if self._sos is not None:
            out, zf = ss.sosfilt(self._sos, out, zi=np.asarray(self._zs))
            self._zs = zf.tolist()
        return out

    def _fir_block(self, e: Array, idx: NDArray[np.int64], lam: Array, v: Array) -> Array:
        """a(k) = sum_j g_v(j) e(k-j), g_v linear between the entries ``idx`` and ``idx + 1``
        by ``lam``, then the warped samples corrected. Per chunk, entry by entry: one used
        on few samples (a fast sweep) by dot products, one used on more by FFT (a hand's
        second uses ~20 entries on 40-120 samples each)."""
        n_fir = self._n_fir
        nfft = self._nfft
        step = nfft - n_fir + 1
        pos = self._epos
        full = np.concatenate([self._ebuf[pos:pos + n_fir - 1][::-1], e])
        y = np.zeros(e.size)
        for a in range(0, e.size, step):
            b = min(a + step, e.size)
            x = full[a:b + n_fir - 1]
            spec = None
            # Every (sample, entry, weight): 1 - lam on the lower entry, lam on the upper,
            # grouped by entry, each group's samples ascending.
            entry = np.concatenate([idx[a:b], idx[a:b] + 1])
            sample = np.tile(np.arange(b - a), 2)
            order = np.lexsort((sample, entry))
            entry, sample = entry[order], sample[order]
            weight = np.concatenate([1.0 - lam[a:b], lam[a:b]])[order]
            edges = np.flatnonzero(np.diff(entry)) + 1
            for lo, hi in zip(np.r_[0, edges], np.r_[edges, entry.size], strict=True):
                j, k, wj = int(entry[lo]), sample[lo:hi], weight[lo:hi]
                if hi - lo < _DIRECT_MAX:
                    k0, k1 = int(k[0]), int(k[-1]) + 1
                    if k1 - k0 == k.size:  # ascending, unique: one stretch of samples
                        y[a + k0:a + k1] += wj * np.correlate(x[k0:k1 + n_fir - 1],
                                                              self.fir[j, ::-1], "valid")
                    else:
                        win = np.lib.stride_tricks.sliding_window_view(x, n_fir)[k]
                        y[a + k] += wj * (win @ self._fir_rev[j])
                    continue
                if spec is None:
                    spec = sfft.rfft(x, nfft)
                z = sfft.irfft(spec * sfft.rfft(self.fir[j], nfft), nfft)
                y[a + k] += wj * z[n_fir - 1 + k]
        self._warp_block(y, full, v, idx, lam)
        self._ebuf[:] = np.tile(full[::-1][:n_fir], 2)
        self._epos = 0
        return y

    def _warp_block(self, y: Array, full: Array, v: Array, idx: NDArray[np.int64],
                    lam: Array) -> None:
        """Replace, in place, the plain first ``_lags`` taps by the warped ones on the
        samples :func:`lag_speeds` warps: of those whose last ``_lags`` history speeds
        ``v`` reach beyond the slack from the current one (else no lag mean can)."""
        lags, n_fir = self._lags, self._n_fir
        vpos = self._vpos
        hv = np.concatenate([self._vbuf[vpos:vpos + lags - 1][::-1], v])
        self._vbuf[:] = np.tile(hv[::-1][:lags], 2)
        self._vpos = 0
        o = (lags - 1) // 2  # a trailing window: sample i's last `lags` speeds
        slack = self.warp_slack_mm_s
        cand = np.flatnonzero((maximum_filter1d(hv, lags, origin=o)[lags - 1:] - v > slack)
                              | (v - minimum_filter1d(hv, lags, origin=o)[lags - 1:] > slack))
        if cand.size == 0:
            return
        windows = np.lib.stride_tricks.sliding_window_view(hv, lags)
        # Each sample's last `lags` noise values, newest first: its taps' partners.
        noise = np.lib.stride_tricks.sliding_window_view(full[n_fir - lags:], lags)
        for a in range(0, cand.size, 512):  # (512, lags) taps at a time
            i = cand[a:a + 512]
            u, warped = lag_speeds(windows[i, ::-1], slack, self._fade)
            i, u = i[warped], u[warped]
            if i.size:
                # The warped taps less the plain ones (the tails are the same: u ends at v).
                k, w = idx[i], lam[i, None]
                plain = (1.0 - w) * self.fir[k, :lags] + w * self.fir[k + 1, :lags]
                dg = warped_responses(self.fir[:, :lags], self._v0, self.table.step_mm_s,
                                      u) - plain
                y[i] += np.einsum("ij,ij->i", dg, noise[i, ::-1])

    def _direct_block(self, e: Array, idx: NDArray[np.int64]) -> Array:
        """Eq. 5 over each run of one filter by lfilter, its zi rebuilt from the history."""
        t = self.table
        y = np.empty(e.size)
        p = self.p
        cuts = np.flatnonzero(np.diff(idx)) + 1
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, e.size], strict=True):
            i = idx[a]
            if i != self._last_i:
                self._limit_history(i)
            hist = self._buf[self._pos:self._pos + p]  # newest first
            zi = -np.correlate(t.polys[i, 1:], hist, "full")[p - 1:]
            y[a:b], _ = ss.lfilter([t.sigma[i]], t.polys[i], e[a:b], zi=zi)
            m = min(b - a, p)  # push the run's newest outputs onto the history
            self._buf[:] = np.tile(np.concatenate([y[a:b][::-1][:m], hist[:p - m]]), 2)
            self._pos = 0
        return y

    def _limit_history(self, i: int) -> None:
        """Entering filter ``i``: cap the history's energy (``history_cap``)."""
        cap2 = self._cap2[i] if abs(i - self._last_i) <= 1 else self._cap2_jump[i]
        self._last_i = i
        h = self._buf[self._pos:self._pos + self.p]
        e = float(np.dot(h, h))
        if e > cap2:
            self._buf *= math.sqrt(cap2 / e)

    def warmup(self, speed_mm_s: float, seconds: float = 0.5) -> None:
        """Run the filter unheard into the stationary process at this speed (the FIR's
        speed history held at it too)."""
        if seconds > 0:
            self.block(speed_mm_s, True, round(seconds * self.fs_hz))
        if self.structure == "fir" and math.isfinite(speed_mm_s):
            self._v_last = min(max(float(speed_mm_s), 0.0), _HISTORY_MAX_MM_S)
            self._vbuf[:] = self._v_last
            self._vpos = 0


def synthesize(model: TextureModel, speed_mm_s: ArrayLike, *, seed: int | None = None
               ) -> Array:
    """Offline synthesis along a speed trace (contact throughout), after a 0.5 s warm-up
    at its first speed."""
    v = np.atleast_1d(np.asarray(speed_mm_s, float))
    r = TextureRenderer(model, seed=seed, ramp_s=1e-6)
    r.warmup(float(v[0]) if v.size else 0.0, 0.5)
    return r.block(v, True, v.size)
