"""HaTT model sets (:mod:`.toolkit`) as a texture family (kind ``"penn"``, Culbertson 2014):
the toolkit's interpolated models tabled on a (speed, force) grid at load, ``render`` and the
1 kHz ``tick`` taking the nearest grid point's (docs/texture.md, "Rendering HaTT models").
"""

from __future__ import annotations

import math
import warnings
from fractions import Fraction
from itertools import pairwise

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.families.penn.toolkit import PennModelSet, barycentric_weights, read_penn
from fydpad.texture.family import FamilyBase, FingerBlock, Kind, hold_finite
from fydpad.texture.lpc.lsf import lsf_to_poly

Array = NDArray[np.float64]
_NOISE_TICKS = 512  # ticks of noise drawn at once
#: Largest tick-matrix table (bytes); the grid shrinks to fit it for high orders.
_TABLE_BYTES = 32 << 20


def decimation_sos(ratio: int, rate_hz: float) -> Array:
    """The anti-alias low-pass before keeping every ``ratio``-th sample: elliptic, 0.1 dB
    ripple to 0.45 x ``rate_hz``, 60 dB from 0.55 x ``rate_hz``; none for ``ratio`` 1."""
    if ratio == 1:
        return np.zeros((0, 6))
    fs = ratio * rate_hz
    order, wn = ss.ellipord(0.45 * rate_hz, 0.55 * rate_hz, 0.1, 60.0, fs=fs)
    return ss.ellip(order, 0.1, 60.0, wn, fs=fs, output="sos")


class PennTexture(FamilyBase):
    """A HaTT model set behind the family contract; parameter ``seed``: the noise's."""

    kind = "penn"
    tick_channels = ("vibration",)
    needs = frozenset({"speed_mm_s", "force_n"})

    def __init__(self, ms: PennModelSet, path: str | None = None, *, seed: int | None = None):
        super().__init__()
        self.ms, self.path, self.surface = ms, path or ms.name, ms.name
        self.rate_hz = 1000.0  # until prepare(rate_hz)
        self.channels = {"vibration": self.rate_hz}
        self.parameters = {"seed": seed}
        self.still_mm_s, self.ramp_s = 1.0, 0.005  # silent below 1 mm/s, faded over 5 ms
        self.p, self.q = ms.ar_lsf.shape[1], ms.ma_lsf.shape[1]
        # The (speed, force) grid: 64 x 32, shrunk until its tick matrices (_tick_matrices,
        # with the low-pass prepare() will build) fit in _TABLE_BYTES.
        ns, nf = 64, 32
        ratio = max(1, round(ms.fs_hz / self.rate_hz))
        d = self.p + self.q + 2 * decimation_sos(ratio, self.rate_hz).shape[0]
        while ns * nf * 8 * (d + 1) * (d + ratio) > _TABLE_BYTES and ns * nf > 64:
            ns, nf = max(8, ns * 3 // 4), max(8, nf * 3 // 4)
        self._grid = ns, nf
        self.speed_grid_mm_s = np.linspace(0.0, ms.max_speed_mm_s, ns)
        self.force_grid_n = np.linspace(0.0, ms.max_force_n, nf)
        s, f = np.meshgrid(self.speed_grid_mm_s, self.force_grid_n, indexing="ij")
        w = barycentric_weights(ms, s.ravel(), f.ravel())  # (cells, models)
        self.den = lsf_to_poly(w @ ms.ar_lsf)
        self.sigma = np.sqrt(np.maximum(w @ ms.var, 0.0))
        # B (order 0 in AR files: [1]) times the gain (1 in AR files, toolkit.read_penn).
        self.num = (w @ ms.gain)[:, None] * lsf_to_poly(w @ ms.ma_lsf)
        self._inv_ds = (ns - 1) / ms.max_speed_mm_s if ms.max_speed_mm_s > 0 else 0.0
        self._inv_df = (nf - 1) / ms.max_force_n if ms.max_force_n > 0 else 0.0
        self.default_force_n = float(np.median(ms.forces_n))
        self._tick_ready = False
        self._rng = np.random.default_rng(seed)
        self.clamped = False
        self.reset()

    def cells(self, speed_mm_s: Array, force_n: Array) -> NDArray[np.int64]:
        """The nearest grid point of each (speed, force)."""
        ns, nf = self._grid
        i = np.clip(np.rint(np.nan_to_num(speed_mm_s) * self._inv_ds), 0, ns - 1)
        j = np.clip(np.rint(np.nan_to_num(force_n) * self._inv_df), 0, nf - 1)
        return (i * nf + j).astype(np.int64)

    def _warn_clamp(self, speed_mm_s: float, force_n: float) -> None:
        ms = self.ms
        if not self.clamped and (speed_mm_s > ms.max_speed_mm_s or force_n > ms.max_force_n):
            self.clamped = True
            warnings.warn(f"{self.path}: speed {speed_mm_s:.1f} mm/s, force {force_n:.2f} N "
                          f"beyond the models' {ms.max_speed_mm_s:g} mm/s, "
                          f"{ms.max_force_n:g} N: clamped to them", stacklevel=3)

    def set_parameter(self, name: str, value: int | None) -> None:
        super().set_parameter(name, value)
        self._rng = np.random.default_rng(value)

    def reset(self) -> None:
        """A new stroke: zero every filter state and the gain ramps."""
        self._yh, self._eh = np.zeros(self.p), np.zeros(self.q)  # render's, newest first
        self._rzi: Array | None = None
        self._rg, self._f, self._g = 0.0, math.nan, 0.0
        if self._tick_ready:
            self._state[:] = 0.0

    def check_rate(self, rate_hz: float) -> int:
        """R = SampleRate / ``rate_hz``; a UserError naming the file unless whole, >= 1."""
        ratio = self.ms.fs_hz / rate_hz
        r = round(ratio)
        if r < 1 or abs(ratio - r) > 1e-9 * ratio:
            raise UserError(f"{self.path}: <SampleRate> {self.ms.fs_hz:g} Hz is not a whole "
                            f"multiple of the render rate {rate_hz:g} Hz")
        return r

    def prepare(self, rate_hz: float) -> None:
        r = self.ratio = self.check_rate(rate_hz)
        self.rate_hz = self.channels["vibration"] = float(rate_hz)
        self.sos = decimation_sos(r, self.rate_hz)
        self._W = self._tick_matrices(r, self.sos)
        d = self._d = self._W.shape[1] - 1
        self._state = np.zeros(d + r)  # [y hist, e hist, low-pass state, R noises]
        self._out = np.zeros(d + 1)
        # Views made once: indexing a list of them in tick creates no array object.
        self._rows = list(self._W)
        self._hist, self._next = self._state[:d], self._out[:d]
        self._st_noise = self._state[d:]
        self._noise = np.zeros((_NOISE_TICKS, r))
        self._noise_rows, self._npos = list(self._noise), _NOISE_TICKS
        self._alpha = 1.0 - math.exp(-1.0 / (self.ramp_s * self.rate_hz))
        self._tick_ready = True

    def _tick_matrices(self, r: int, sos: Array) -> Array:
        """W (cells, d + 1, d + r): one tick of R model samples as a linear map of
        v = [y(k-1..k-p), e(k-1..k-q), low-pass state, n(1..R)] (n standard normal) to
        the next state and, in the last row, the low-pass output at the R-th sample."""
        a, bg, sig = self.den, self.num, self.sigma
        c, p, q, s = a.shape[0], self.p, self.q, sos.shape[0]
        d = p + q + 2 * s
        eye = np.eye(d + r)
        yh = np.repeat(eye[None, :p], c, axis=0)  # each state variable as a row over v
        eh = np.repeat(eye[None, p:p + q], c, axis=0)
        z = np.repeat(eye[None, p + q:d].reshape(1, s, 2, d + r), c, axis=0)
        for k in range(r):
            e = sig[:, None] * eye[d + k][None, :]
            y = (bg[:, :1] * e - np.einsum("cp,cpd->cd", a[:, 1:], yh)
                 + np.einsum("cq,cqd->cd", bg[:, 1:], eh))
            eh = np.concatenate([e[:, None], eh], axis=1)[:, :q]
            yh = np.concatenate([y[:, None], yh], axis=1)[:, :p]
            x = y
            for j in range(s):  # transposed direct form II, as scipy's sosfilt
                b0, b1, b2, _, a1, a2 = sos[j]
                o = b0 * x + z[:, j, 0]
                z[:, j, 0] = b1 * x - a1 * o + z[:, j, 1]
                z[:, j, 1] = b2 * x - a2 * o
                x = o
        w = np.concatenate([yh, eh, z.reshape(c, 2 * s, d + r), x[:, None]], axis=1)
        return np.ascontiguousarray(w)

    def tick(self, t_s: float, contact: bool, x_mm: float, y_mm: float,
             speed_mm_s: float, force_n: float) -> tuple[float]:
        if not self._tick_ready:
            raise RuntimeError(f"{self.path}: prepare(rate_hz) before the first tick")
        v = speed_mm_s if speed_mm_s == speed_mm_s else 0.0
        if force_n == force_n and force_n != math.inf:
            self._f = force_n
        f = self._f if self._f == self._f else self.default_force_n
        ns, nf = self._grid
        i = int(v * self._inv_ds + 0.5)
        if i >= ns:
            i = ns - 1
            self._warn_clamp(v, f)
        fj = f * self._inv_df + 0.5
        j = int(fj) if fj > 0.0 else 0
        if j >= nf:
            j = nf - 1
            self._warn_clamp(v, f)
        pos = self._npos
        if pos >= _NOISE_TICKS:
            self._rng.standard_normal(out=self._noise)
            pos = 0
        np.copyto(self._st_noise, self._noise_rows[pos])
        self._npos = pos + 1
        np.dot(self._rows[i * nf + j], self._state, out=self._out)
        np.copyto(self._hist, self._next)
        target = 1.0 if (contact and v >= self.still_mm_s) else 0.0
        self._g += self._alpha * (target - self._g)
        return (self._g * self._out.item(self._d),)  # item: a float, not a NumPy scalar

    def render(self, finger: FingerBlock, channel: str = "vibration") -> Array:
        """The block's vibration at ``finger.fs_hz`` from its speed and force (m/s^2)."""
        self.check_channel(channel)
        n = finger.t_s.size
        if n == 0:
            return np.zeros(0)
        fs, fo = self.ms.fs_hz, float(finger.fs_hz)
        speed = np.where(np.isfinite(finger.speed_mm_s), finger.speed_mm_s, 0.0)
        force = hold_finite(finger.force_n, self._f if self._f == self._f
                             else self.default_force_n)
        self._f = float(force[-1])
        bad = (speed > self.ms.max_speed_mm_s) | (force > self.ms.max_force_n)
        if bad.any():
            k = int(np.argmax(bad))
            self._warn_clamp(float(speed[k]), float(force[k]))
        cells, on = self.cells(speed, force), finger.contact & (speed >= self.still_mm_s)
        ratio = fs / fo
        r = round(ratio)
        whole = r >= 1 and abs(ratio - r) <= 1e-9 * ratio
        at = np.minimum((np.arange(round(n * ratio)) / ratio).astype(np.int64), n - 1)
        y = self._arma(np.repeat(cells, r) if whole else cells[at])
        alpha = 1.0 - math.exp(-1.0 / (self.ramp_s * (fo if whole else fs)))
        if whole:
            if r > 1:
                sos = decimation_sos(r, fo)
                if self._rzi is None or self._rzi.shape[0] != sos.shape[0]:
                    self._rzi = np.zeros((sos.shape[0], 2))
                y, self._rzi = ss.sosfilt(sos, y, zi=self._rzi)
                y = y[r - 1::r]
            return y * self._ramp(on.astype(float), alpha)
        y = y * self._ramp(on[at].astype(float), alpha)
        fr = Fraction(fo / fs).limit_denominator(1000)
        out = ss.resample_poly(y, fr.numerator, fr.denominator)
        return np.pad(out[:n], (0, max(0, n - out.size)))

    def _ramp(self, target: Array, alpha: float) -> Array:
        g, _ = ss.lfilter([alpha], [1.0, alpha - 1.0], target, zi=[(1.0 - alpha) * self._rg])
        self._rg = float(g[-1])
        return g

    def _arma(self, cells: NDArray[np.int64]) -> Array:
        """The toolkit's recursion at the model rate over runs of one grid point."""
        m = cells.size
        e = self._rng.standard_normal(m) * self.sigma[cells]
        y = np.empty(m)
        edges = np.concatenate([[0], np.flatnonzero(np.diff(cells)) + 1, [m]])
        for s0, s1 in pairwise(edges.tolist()):
            a, b = self.den[cells[s0]], self.num[cells[s0]]
            zi = ss.lfiltic(b, a, self._yh, self._eh)
            y[s0:s1], _ = ss.lfilter(b, a, e[s0:s1], zi=zi)
            self._yh = np.concatenate([y[s0:s1][::-1], self._yh])[:self.p]
            self._eh = np.concatenate([e[s0:s1][::-1], self._eh])[:self.q]
        return y


def _from_json(data: dict, where: str) -> PennTexture:
    raise UserError(f"{where}: penn models are HaTT XML files (penn:FILE.xml), not JSON")


KIND = Kind("penn", _from_json, None, title="HaTT",
            from_file=lambda path: PennTexture(read_penn(path), path))
