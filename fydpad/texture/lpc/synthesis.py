"""Texture synthesis at the output rate (paper eq. 5, Fig. 9).

    a(k) = e(k) + h^T [a(k-1) ... a(k-p)],   e ~ N(0, sigma^2)

with (h, sigma^2) interpolated at the current finger speed. Two filter structures:

- ``"direct"``: eq. 5 itself; the state is the last p outputs. The paper's structure;
  the default for the ``"nearest"`` interpolation (the paper's per-speed fits).
- ``"fir"``: the same process written as its moving average,
  a(k) = sum_j g_v(j) e(k-j), with g_v the impulse response of sigma / A(z) at the
  current speed, truncated where less than 1e-4 of its energy remains (at most
  ``FIR_MAX`` samples); the state is the last noise samples. The default for
  ``"stretch"`` (the calibrated spectrum), whose lines glide with speed as a surface's
  do: a direct-form recursion whose resonances glide pumps energy (measured: the output 2-7x its
  stationary RMS on the generator's strokes, LSD up to 26 dB), while here the output
  variance at every sample is exactly that of the current filter, whatever the
  switching. Cost: two dot products of the response's length (<= 2048 here) per sample.
  When the speed changes fast (a stroke's start or stop), lag j takes the filter of
  the mean speed over that lag instead of the current one (:mod:`fir_warp`): the
  current filter on old noise rings a gliding line at the wrong frequency. Cost: the
  mean of the last 512 speeds every sample (one cumulative sum), and where warped 512
  taps gathered from the table.

Both structures have two paths that share one state and one noise stream, so they
give the same samples:

- :meth:`TextureRenderer.tick` for the station's 1 kHz loop: one sample, no array
  allocation, a table lookup instead of interpolation;
- :meth:`TextureRenderer.block` for offline use: over runs of constant filter,
  ``scipy.signal.lfilter`` with its ``zi`` rebuilt from the output history at every
  filter change, so a model change continues eq. 5 exactly (no click); or the FIR
  convolution over the run with the noise history in front.

Silence: no contact, or speed below ``STILL_MM_S``. Below the slowest model's range
(its speed minus the fit tolerance) the slowest model fades out linearly with speed;
above the fastest model's fit range (its speed plus the tolerance) it is clamped
(warned once). The output gain follows its target
through a short one-pole ramp.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from fydpad.texture.lpc.analysis import energy_length, impulse_responses
from fydpad.texture.lpc.fir_warp import (
    WARP_LAGS,
    WARP_SLACK_MM_S,
    lag_fade,
    lag_speeds,
    table_position,
    warped_responses,
)
from fydpad.texture.lpc.interpolation import SpeedTable, build_table
from fydpad.texture.lpc.model_file import TextureModel
from vision.speed import SpeedState, speed_update

Array = NDArray[np.float64]
_NOISE_CHUNK = 4096
_DIRECT_MAX = 48  # an entry used on fewer samples of a block chunk: dot products, not FFT
_HISTORY_MAX_MM_S = 1e4  # the warp's speed history is clamped to [0, this]
STILL_MM_S = 1.0  # slower is a finger at rest: silence
FIR_MAX = 4096  # longest FIR response (taps)


class TextureRenderer:
    """Eq. 5 for one texture model; see the module docstring for the two paths."""

    #: At a filter change the history may hold at most this many times the new filter's
    #: stationary RMS. A direct-form AR filter switched between high-gain models is not
    #: stable just because each model is: the old history excites the new filter's modes
    #: and repeated switching pumps energy (measured: 1e60 within 10 s when the speed
    #: jumps every 25 ms on a 60 dB-range texture). Scaling the history down at a
    #: switch bounds the output; with a hand's smooth speed it never acts.
    history_cap = 3.0
    #: The cap when the speed jumps by more than one table step at once (not a hand's
    #: smooth speed: a tracking glitch or a new contact): tighter.
    jump_cap = 1.0

    def __init__(
        self, model: TextureModel, *, method: str | None = None, step_mm_s: float = 0.25,
        seed: int | None = None, ramp_s: float = 0.005, drive_filter: bool = False,
        structure: str | None = None, warp_slack_mm_s: float = WARP_SLACK_MM_S,
    ):
        """``method``: the interpolation (default the model's); ``structure``: "fir" or
        "direct" (default: "fir" for "stretch"); ``warp_slack_mm_s``: inf for the plain
        FIR (fir_warp.py); ``drive_filter``: band-pass the output through the model's
        drive band (order-2 Butterworth)."""
        if model.fs_hz <= 0:
            raise ValueError("model sample rate must be positive")
        self.model = model
        self.fs_hz = float(model.fs_hz)
        method = model.interpolation if method is None else method
        self.table: SpeedTable = build_table(model, method, step_mm_s)
        if not self.table.stable.all():
            bad = self.table.speeds_mm_s[~self.table.stable]
            warnings.warn(
                f"{model.surface}: {bad.size} interpolated filters of method {method!r} are "
                f"unstable ({bad.min():g}-{bad.max():g} mm/s); they are replaced by the "
                "nearest fitted model", stacklevel=2)
            self._replace_unstable()
        self.method = method
        self.structure = structure or ("fir" if method == "stretch" else "direct")
        if self.structure not in ("direct", "fir"):
            raise ValueError(f"filter structure must be 'direct' or 'fir', not {structure!r}")
        self.p = model.order
        self.v_min = float(model.speeds_mm_s[0])
        self.v_max = float(model.speeds_mm_s[-1])
        # The slowest model was fitted on speeds down to v_min - tolerance: it holds
        # there; below that it fades out linearly to silence at 0 mm/s.
        self.fade_below_mm_s = max(self.v_min - model.tolerance_mm_s, 0.5 * self.v_min)
        self.clamp_above_mm_s = self.v_max + float(model.tolerance_mm_s)
        self.still_mm_s = STILL_MM_S
        self.gain = float(model.gain)
        self._alpha = 1.0 - math.exp(-1.0 / (max(ramp_s, 1e-9) * self.fs_hz))
        self._rng = np.random.default_rng(seed)
        self._noise = np.empty(_NOISE_CHUNK)
        self._noise_pos = _NOISE_CHUNK
        self._buf = np.zeros(2 * self.p)  # each output written twice: a contiguous window
        self._pos = 0
        self._g = 0.0
        self.clamped = False
        self._last_i = -1
        # Stationary output RMS of every table filter, and the cap on the history's
        # energy at a filter change (see _limit_history).
        self._rms = np.array([
            s * np.sqrt(np.mean(1.0 / np.abs(np.fft.rfft(a, 8192)) ** 2))
            for s, a in zip(self.table.sigma, self.table.polys, strict=True)])
        self._cap2 = (self.history_cap * self._rms) ** 2 * self.p
        self._cap2_jump = (self.jump_cap * self._rms) ** 2 * self.p
        slack = float(warp_slack_mm_s)
        if not slack >= 0.0:  # NaN too
            raise ValueError(f"warp_slack_mm_s must be >= 0 (inf: no warp), not {slack!r}")
        self.warp_slack_mm_s = slack  # inf: the plain FIR
        if self.structure == "fir":
            g = impulse_responses(self.table.polys, self.table.sigma, FIR_MAX)
            n_fir = min(max(energy_length(g, 1e-4), 16), FIR_MAX)
            if g.shape[0] == 1:  # one model: two equal rows keep the interpolation uniform
                g = np.vstack([g, g])
            self._use_fir(g[:, :n_fir])  # and the per-sample views
        else:
            self._tick_views()
        band = model.drive_band_hz
        self._sos: Array | None = None
        if drive_filter:
            if band is None:
                raise ValueError("drive filter requested but the model has no drive band")
            self._sos = ss.butter(2, band, "bandpass", fs=self.fs_hz, output="sos")
            # The per-tick path in plain floats (NumPy scalars cost ~5 us a tick here);
            # the block path hands the same state to sosfilt.
            self._sos_rows = [tuple(float(c) for c in row) for row in self._sos]
            self._zs = [[0.0, 0.0] for _ in self._sos_rows]

    def _use_fir(self, fir: Array) -> None:
        """Make ``fir`` (table entries x taps) the FIR structure's responses, with every
        state and scratch buffer that depends on them (histories zeroed)."""
        self._n_fir_rows, n_fir = fir.shape
        self.fir = np.ascontiguousarray(fir)
        self._fir_rev = np.ascontiguousarray(self.fir[:, ::-1])
        # Block path: FFT size, and each table entry's spectrum once it is first used.
        self._nfft = sfft.next_fast_len(n_fir + 1023)  # chunks of >= 1024 samples
        self._gspec = np.empty((self._n_fir_rows, self._nfft // 2 + 1), complex)
        self._gspec_ok = np.zeros(self._n_fir_rows, bool)
        self._ebuf = np.zeros(2 * n_fir)  # noise, newest first, written twice
        self._epos = 0
        # The last speeds, newest first, written twice: each lag's speed (fir_warp).
        lags = min(WARP_LAGS, n_fir)
        self._lags = lags
        self._vbuf = np.zeros(2 * lags)
        self._vpos = 0
        self._v_last = 0.0  # the last finite speed (what a lost track holds)
        self._inv_count = 1.0 / np.arange(1.0, lags + 1.0)
        self._vdev = np.empty(lags)
        self._vclip = np.empty(lags)
        self._fade = lag_fade(lags)
        # Scratch for a warped tick: table positions of the lags, flat indices, taps.
        self._wk = np.empty(lags, np.int64)
        self._wflat = np.empty(lags, np.int64)
        self._ww = np.empty(lags)
        self._g0 = np.empty(lags)
        self._g1 = np.empty(lags)
        # Lag-major copy of the table's first `lags` taps: entry k's tap j at j * rows + k,
        # entry k + 1's next to it.
        self._fir_lag_major = np.ascontiguousarray(self.fir[:, :lags].T).ravel()
        self._lag_base = np.arange(lags) * self._n_fir_rows
        self._fade_per_step = self._fade / float(self.table.step_mm_s)
        self._tick_views()

    def _tick_views(self) -> None:
        """The per-sample path's table rows and history windows as views made once."""
        t = self.table
        self._v0 = float(t.speeds_mm_s[0])
        self._inv_step = 1.0 / float(t.step_mm_s)
        self._sigma = [float(s) for s in t.sigma]
        self._h_rows = list(t.h)
        self._bwin = [self._buf[k:k + self.p] for k in range(self.p)]
        if self.structure == "fir":
            self._n_fir = self.fir.shape[1]
            self._fir_rows = list(self.fir)
            self._ewin = [self._ebuf[k:k + self._n_fir] for k in range(self._n_fir)]
            lags = self._lags
            self._vwin = [self._vbuf[k:k + lags] for k in range(lags)]
            self._ewin_head = [w[:lags] for w in self._ewin]
            self._ewin_tail = [w[lags:] for w in self._ewin]
            self._fir_tails = [row[lags:] for row in self.fir]

    def _replace_unstable(self) -> None:
        t = self.table
        for k in np.flatnonzero(~t.stable):
            j = int(np.argmin(np.abs(self.model.speeds_mm_s - t.speeds_mm_s[k])))
            t.polys[k] = self.model.poly(j)
            t.h[k] = self.model.h[j]
            t.sigma[k] = math.sqrt(self.model.sigma2[j])

    # -------------------------------------------------------------- shared pieces
    def reseed(self, seed: int | None) -> None:
        """Restart the noise e(k) from ``seed``, dropping the pre-drawn chunk (so the
        next samples depend on the seed only, not on what was rendered before)."""
        self._rng = np.random.default_rng(seed)
        self._noise_pos = _NOISE_CHUNK

    def reset(self) -> None:
        """Zero the filter history, the gain and the drive filter."""
        self._buf[:] = 0.0
        if self.structure == "fir":
            self._ebuf[:] = 0.0
            self._vbuf[:] = 0.0
            self._v_last = 0.0
        self._g = 0.0
        self._last_i = -1
        if self._sos is not None:
            for z in self._zs:
                z[0] = z[1] = 0.0

    def target_gain(self, speed_mm_s: float, contact: bool) -> float:
        """Output gain for this speed: 0 when still or without contact, fade below v_min."""
        if not contact or not speed_mm_s >= self.still_mm_s:
            return 0.0
        if speed_mm_s < self.fade_below_mm_s:
            return self.gain * speed_mm_s / self.fade_below_mm_s
        # The fastest model was fitted on speeds up to v_max + tolerance: only beyond its
        # data is the clamp news (a stroke at the fastest speed wanders above it).
        if speed_mm_s > self.clamp_above_mm_s and not self.clamped:
            self.clamped = True
            warnings.warn(
                f"{self.model.surface}: speed {speed_mm_s:.1f} mm/s above the fastest model's "
                f"range ({self.v_max:g} mm/s, fitted within {self.model.tolerance_mm_s:g}): "
                "clamped to it", stacklevel=3)
        return self.gain

    def target_gains(self, v: Array, c: Array) -> Array:
        """Vectorised :meth:`target_gain`."""
        on = c & np.isfinite(v) & (v >= self.still_mm_s)  # as tick: no speed, no contact
        g = np.where(on, self.gain * np.minimum(v / self.fade_below_mm_s, 1.0), 0.0)
        fast = on & (v > self.clamp_above_mm_s)
        if fast.any() and not self.clamped:
            self.target_gain(float(v[np.argmax(fast)]), True)
        return g

    def _history_newest_first(self) -> Array:
        return self._buf[self._pos:self._pos + self.p]

    def _take_noise(self, n: int) -> Array:
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

    # -------------------------------------------------------------- per sample
    def tick(self, speed_mm_s: float, contact: bool = True) -> float:
        """One output sample (m/s^2) for the current speed and contact: eq. 5. A speed that
        is not finite (NaN, inf) is no speed: silence, as a lost track."""
        finite = math.isfinite(speed_mm_s)
        if not finite:  # else the table index raises (NaN, inf)
            speed_mm_s, contact = 0.0, False
        if self._noise_pos >= _NOISE_CHUNK:
            self._rng.standard_normal(out=self._noise)
            self._noise_pos = 0
        e = self._noise[self._noise_pos]
        self._noise_pos += 1
        # Rows and windows are views made once (_tick_views): no view per tick.
        if self.structure == "fir":
            n_fir = self._n_fir
            pos = self._epos
            pos = pos - 1 if pos > 0 else n_fir - 1
            self._ebuf[pos] = e
            self._ebuf[pos + n_fir] = e
            self._epos = pos
            hist = self._ewin[pos]
            # Each lag's speed (fir_warp.lag_speeds, the same operations): the mean of the
            # newest speeds, its deviation from this one.
            lags = self._lags
            vpos = self._vpos
            vpos = vpos - 1 if vpos > 0 else lags - 1
            vh = self._history_speed(speed_mm_s, finite)
            self._vbuf[vpos] = vh
            self._vbuf[vpos + lags] = vh
            self._vpos = vpos
            d = self._vdev
            np.add.accumulate(self._vwin[vpos], out=d)  # np.cumsum, without its wrapper
            d *= self._inv_count
            d -= vh
            # g_v linear between the two entries around the speed: a stepwise g would
            # modulate the output at every step and leak the strong bands into weak ones
            # (measured: 10-20 dB too much power at 250-500 Hz on sandpaper_p80).
            x = (speed_mm_s - self._v0) * self._inv_step
            x = min(max(x, 0.0), self._n_fir_rows - 1.0) if x == x else 0.0
            k = min(int(x), self._n_fir_rows - 2)
            w = x - k
            rows = self._fir_rows
            slack = self.warp_slack_mm_s
            # argmax/argmin, not max/min: their reductions allocate 1 kB a call here
            if d[d.argmax()] > slack or d[d.argmin()] < -slack:
                # The warped lags' taps, then the plain tail (the fade ends at v).
                y = self._warped_head(d, vh, pos)
                if self._n_fir > lags:
                    tails, ht = self._fir_tails, self._ewin_tail[pos]
                    y += (1.0 - w) * float(tails[k].dot(ht)) + w * float(tails[k + 1].dot(ht))
            else:
                y = (1.0 - w) * float(rows[k].dot(hist)) + w * float(rows[k + 1].dot(hist))
        else:
            i = self.table.index(speed_mm_s)
            if i != self._last_i:
                self._limit_history(i)
            pos = self._pos
            p = self.p
            y = self._sigma[i] * e + float(self._h_rows[i].dot(self._bwin[pos]))
            pos = pos - 1 if pos > 0 else p - 1
            self._buf[pos] = y
            self._buf[pos + p] = y
            self._pos = pos
        self._g += self._alpha * (self.target_gain(speed_mm_s, contact) - self._g)
        out = self._g * y
        if self._sos is not None:
            out = self._drive_tick(out)
        return out

    def _warped_head(self, d: Array, speed_mm_s: float, pos: int) -> float:
        """sum_{j < lags} g_{u_j}(j) e(k - j) for the lag deviations ``d`` from the
        history's current speed ``speed_mm_s``: :func:`fir_warp.lag_speeds` and
        :func:`fir_warp.warped_responses` in preallocated buffers."""
        slack = self.warp_slack_mm_s
        # ufuncs, not np.clip: its Python wrapper costs ~2 us a call here
        u = np.maximum(d, -slack, out=self._vclip)
        np.minimum(u, slack, out=u)
        np.subtract(d, u, out=u)
        # The table position (u - v0) / step with the fade folded in (fir_warp's
        # arithmetic up to rounding)
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

    def _history_speed(self, speed_mm_s: float, finite: bool) -> float:
        """The speed the warp's history keeps for this sample: a lost track (not finite)
        holds the last speed; clamped to [0, 1e4] mm/s (a mean of 512 speeds near 1e306
        overflows)."""
        if finite:
            self._v_last = min(max(speed_mm_s, 0.0), _HISTORY_MAX_MM_S)
        return self._v_last

    def _drive_tick(self, x: float) -> float:
        for (b0, b1, b2, _, a1, a2), z in zip(self._sos_rows, self._zs, strict=True):
            # transposed direct form II, as scipy's sosfilt
            y = b0 * x + z[0]
            z[0] = b1 * x - a1 * y + z[1]
            z[1] = b2 * x - a2 * y
            x = y
        return x

    # -------------------------------------------------------------- per block
    def block(self, speed_mm_s: ArrayLike, contact: ArrayLike = True,
              n: int | None = None) -> Array:
        """``n`` samples for per-sample (or constant) speed and contact; same as ``tick``."""
        v = np.asarray(speed_mm_s, float)
        c = np.asarray(contact, bool)
        if n is None:
            n = max(v.size, c.size)
        if n == 0:
            return np.zeros(0)
        v = np.broadcast_to(v, (n,))
        c = np.broadcast_to(c, (n,))
        t = self.table
        e = self._take_noise(n)
        if self.structure == "fir":
            # A speed that is not finite is no speed (as in tick): the first entry.
            v0 = float(t.speeds_mm_s[0])
            idx, lam = table_position(np.where(np.isfinite(v), v, v0), v0, t.step_mm_s,
                                      self._n_fir_rows)
        else:
            idx = np.clip(((v - t.speeds_mm_s[0]) / t.step_mm_s + 0.5).astype(np.int64)
                          if n else np.zeros(0, np.int64), 0, t.h.shape[0] - 1)
            idx[~np.isfinite(v)] = 0
        cuts = np.flatnonzero(np.diff(idx)) + 1
        starts = np.concatenate([[0], cuts]).astype(int)
        stops = np.concatenate([cuts, [n]]).astype(int)
        if self.structure == "fir":
            y = self._fir_block(e, idx, lam, starts, stops, self._history_speeds(v))
        else:
            y = self._direct_block(e, idx, starts, stops)
        target = self.target_gains(v, c)
        g, _zf = ss.lfilter([self._alpha], [1.0, self._alpha - 1.0], target,
                           zi=[(1.0 - self._alpha) * self._g])
        if n:
            self._g = float(g[-1])
        out = g * y
        if self._sos is not None:
            out, zf = ss.sosfilt(self._sos, out, zi=np.asarray(self._zs))
            self._zs = zf.tolist()
        return out

    def _fir_block(self, e: Array, idx: NDArray[np.int64], lam: Array,
                   starts: NDArray[np.int64], stops: NDArray[np.int64], v: Array) -> Array:
        """a(k) = sum_j g_v(j) e(k-j), the noise history in front; g_v linear between the
        two table entries around the speed, as in ``tick``; then the samples whose lags
        are warped (:mod:`fir_warp`) again, by their own responses.

        Over chunks of up to nfft - n_fir + 1 samples, entry by entry: an entry used on
        few samples (a fast sweep) by dot products on those samples; one used on more by
        FFT, the chunk's noise transformed once and multiplied by the entry's cached
        spectrum (a hand's second uses ~20 entries, each on 40-120 samples: too short
        for a convolution each, too long for dot products)."""
        n_fir = self.fir.shape[1]
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
            m = b - a
            entry = np.concatenate([idx[a:b], idx[a:b] + 1])
            sample = np.concatenate([np.arange(m), np.arange(m)])
            order = np.lexsort((sample, entry))
            entry = entry[order]
            sample = sample[order]
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
                z = sfft.irfft(spec * self._entry_spectrum(j), nfft)
                y[a + k] += wj * z[n_fir - 1 + k]
        self._warp_block(y, full, v, idx, lam)
        newest = full[::-1][:n_fir]
        self._ebuf[:n_fir] = newest
        self._ebuf[n_fir:] = newest
        self._epos = 0
        return y

    def _history_speeds(self, v: Array) -> Array:
        """:meth:`_history_speed` over a block: not finite holds the last finite speed."""
        ok = np.isfinite(v)
        h = np.clip(np.where(ok, v, 0.0), 0.0, _HISTORY_MAX_MM_S)
        if not ok.all():
            last = np.maximum.accumulate(np.where(ok, np.arange(v.size), -1))
            h = np.where(last >= 0, h[np.maximum(last, 0)], self._v_last)
        if v.size:
            self._v_last = float(h[-1])
        return h

    def _warp_block(self, y: Array, full: Array, v: Array, idx: NDArray[np.int64],
                    lam: Array) -> None:
        """Correct the samples whose lags are warped, in place: those whose window of the
        last ``_lags`` history speeds ``v`` reaches further than the slack from the
        current one (else no lag's mean speed can) and, of these, those
        :func:`fir_warp.lag_speeds` says so; their first ``_lags`` plain taps (table
        entries ``idx``, ``idx + 1`` mixed by ``lam``, as the plain pass used) are
        replaced by the warped ones."""
        lags, n_fir = self._lags, self.fir.shape[1]
        vpos = self._vpos
        hv = np.concatenate([self._vbuf[vpos:vpos + lags - 1][::-1], v])
        newest = hv[::-1][:lags]
        self._vbuf[:lags] = newest
        self._vbuf[lags:] = newest
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
        step = self.table.step_mm_s
        for a in range(0, cand.size, 512):  # (512, lags) taps at a time
            i = cand[a:a + 512]
            u, warped = lag_speeds(windows[i, ::-1], slack, self._fade)
            i, u = i[warped], u[warped]
            if i.size:
                # The warped taps less the plain ones (the tails are the same: u ends at v).
                k, w = idx[i], lam[i, None]
                plain = (1.0 - w) * self.fir[k, :lags] + w * self.fir[k + 1, :lags]
                dg = warped_responses(self.fir[:, :lags], self._v0, step, u) - plain
                y[i] += np.einsum("ij,ij->i", dg, noise[i, ::-1])

    def _entry_spectrum(self, j: int) -> NDArray[np.complex128]:
        """rfft of table entry j's response at the block FFT size (computed once)."""
        if not self._gspec_ok[j]:
            self._gspec[j] = sfft.rfft(self.fir[j], self._nfft)
            self._gspec_ok[j] = True
        return self._gspec[j]

    def _direct_block(self, e: Array, idx: NDArray[np.int64], starts: NDArray[np.int64],
                      stops: NDArray[np.int64]) -> Array:
        """Eq. 5 over each run by lfilter, its zi rebuilt from the output history."""
        t = self.table
        y = np.empty(e.size)
        p = self.p
        for a, b in zip(starts, stops, strict=True):
            i = idx[a]
            if i != self._last_i:
                self._limit_history(i)
            hist = self._history_newest_first()
            zi = -np.correlate(t.polys[i, 1:], hist, "full")[p - 1:]
            y[a:b], _ = ss.lfilter([t.sigma[i]], t.polys[i], e[a:b], zi=zi)
            self._push_history(y[a:b])
        return y

    def _limit_history(self, i: int) -> None:
        """Entering filter ``i``: cap the history's energy (see ``history_cap``)."""
        cap2 = self._cap2[i] if abs(i - self._last_i) <= 1 else self._cap2_jump[i]
        self._last_i = i
        p = self.p
        h = self._buf[self._pos:self._pos + p]
        e = float(np.dot(h, h))
        if e > cap2:
            self._buf *= math.sqrt(cap2 / e)

    def _push_history(self, y: Array) -> None:
        p = self.p
        m = min(y.size, p)
        newest = y[::-1][:m]
        pos = self._pos
        hist = np.concatenate([newest, self._buf[pos:pos + p - m]])
        self._buf[:p] = hist
        self._buf[p:] = hist
        self._pos = 0

    def warmup(self, speed_mm_s: float, seconds: float = 0.5) -> None:
        """Run the filter (unheard) so its state is the stationary process at this speed
        (the FIR's speed history held at it too: 0.5 s is shorter than its 512 lags)."""
        if seconds > 0:
            self.block(speed_mm_s, True, round(seconds * self.fs_hz))
        if self.structure == "fir" and math.isfinite(speed_mm_s):
            self._vbuf[:] = self._history_speed(float(speed_mm_s), True)
            self._vpos = 0


def synthesize(
    model: TextureModel, speed_mm_s: ArrayLike, *, seed: int | None = None,
    method: str | None = None, warmup_s: float = 0.5, n: int | None = None,
) -> Array:
    """Offline synthesis along a speed trace (contact throughout), after a warm-up."""
    v = np.asarray(speed_mm_s, float)
    if n is None:
        n = v.size
    r = TextureRenderer(model, method=method, seed=seed, ramp_s=1e-6)
    r.warmup(float(np.broadcast_to(v, (max(n, 1),))[0]), warmup_s)
    return r.block(v, True, n)


@dataclass
class CentroidSpeed:
    """Finger speed for every 1 kHz tick from the camera-rate contact centroid.

    ``position(t_s, x_mm, y_mm, contact)`` at each camera frame differentiates the
    centroid (``vision.speed.speed_update``, whose own low-pass we bypass with a high
    cutoff); ``tick(dt_s)`` at 1 kHz holds that raw velocity between frames (i.e. it
    extrapolates the position linearly) and applies the paper's 10 Hz low-pass at the
    tick rate, so the speed is smooth rather than a 30 Hz staircase.

    ``sample(t_s, x_mm, y_mm, contact)`` takes the newest centroid at every tick (held
    between frames, as the station's render loop sees it): a changed one is a new frame,
    differentiated once; one unchanged for ``rest_after_s`` is a finger at rest (without
    that, ``tick`` would hold the last frame's velocity for ever).
    """

    cutoff_hz: float = 10.0
    #: Longer than a frame period at the slowest vision rate (the paper's 10 Hz).
    rest_after_s: float = 0.25
    contact: bool = False
    _last_x_mm: float = math.nan
    _last_y_mm: float = math.nan
    _last_contact: bool = False
    _t_new_s: float = -math.inf
    _state: SpeedState | None = None
    _vx: float = 0.0
    _vy: float = 0.0
    _fx: float = 0.0
    _fy: float = 0.0

    def position(self, t_s: float, x_mm: float, y_mm: float, contact: bool) -> None:
        state = self._state or SpeedState()
        was = self.contact and math.isfinite(state.x_mm)
        _, new = speed_update(state, t_s, x_mm, y_mm, contact, cutoff_hz=1e9)
        self._state = new
        self.contact = bool(contact)
        if not contact:
            self._vx = self._vy = self._fx = self._fy = 0.0
        elif was:
            self._vx, self._vy = new.vx_mm_s, new.vy_mm_s

    def sample(self, t_s: float, x_mm: float, y_mm: float, contact: bool) -> None:
        """The newest centroid at a tick: :meth:`position` once per new frame; a zero
        velocity once it has stayed put for ``rest_after_s``."""
        # Without contact the position is NaN: only the change to "no contact" is news.
        if contact != self._last_contact or (
                contact and (x_mm != self._last_x_mm or y_mm != self._last_y_mm)):
            self.position(t_s, x_mm, y_mm, contact)
            self._last_x_mm, self._last_y_mm, self._last_contact = x_mm, y_mm, contact
            self._t_new_s = t_s
        elif contact and t_s - self._t_new_s >= self.rest_after_s:
            # At rest; the next frame is still differentiated from the last real one (a
            # new time base here would divide its step by too short a time).
            self._vx = self._vy = 0.0

    def tick(self, dt_s: float = 1e-3) -> float:
        """Advance the low-pass by ``dt_s``; the filtered speed in mm/s (0 without contact)."""
        if not self.contact:
            return 0.0
        a = 1.0 - math.exp(-2.0 * math.pi * self.cutoff_hz * dt_s)
        self._fx += a * (self._vx - self._fx)
        self._fy += a * (self._vy - self._fy)
        return math.hypot(self._fx, self._fy)
