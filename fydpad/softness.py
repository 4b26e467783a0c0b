"""Softness rendering (paper section III-A and IV-A).

The FYD-pad renders a stiffness by the stretch of its fabric: the two motors wind the
fabric to a position theta, and the fabric then answers a finger's indentation delta
with a force F = k(theta) * delta. The paper characterised k(theta) with a
finger-shaped indenter (Fig. 6: linear curves, R^2 > 0.932, 0.262-1.04 N/mm) and used
the characterisation as a look-up table: a requested stiffness gives the motor
position. Specimens were characterised the same way (F = lambda * delta, R^2 > 0.924:
0.88 N/mm for SS1/SS2, 0.39 N/mm for SS3/SS4) so the pad can render them by name.

Pure functions and small classes over NumPy arrays; file I/O is limited to the table's
own CSV (``save_table`` / ``load_table``), laid out in ``docs/softness.md``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError

#: The paper's reproducible stiffness range (section III-A), N/mm.
PAPER_RANGE_N_PER_MM = (0.262, 1.04)


class SoftnessError(UserError):
    """A softness request or characterisation that cannot be honoured (names the cause)."""


class SoftnessWarning(UserWarning):
    """A fit below the paper's R^2, or a request clamped to the characterised range."""


@dataclass(frozen=True)
class SoftnessConfig:
    """Softness settings; defaults are the paper's (section III-A, IV-A)."""

    #: Warn when a fabric fit's R^2 is below this (paper: R^2 > 0.932 for every theta).
    r2_warn: float = 0.932
    #: Warn when a specimen fit's R^2 is below this (paper: R^2 > 0.924).
    specimen_r2_warn: float = 0.924
    #: Refuse (instead of clamping) a stiffness outside the characterised range.
    strict: bool = False
    #: The table file (``fydpad softness calibrate --out``); empty: none configured.
    table: str = ""
    #: Live estimate: a press starts when the indentation exceeds this (mm)...
    press_start_mm: float = 1.0
    #: ...and ends when it falls below this (mm); hysteresis against IR noise.
    press_end_mm: float = 0.5
    #: Live estimate: samples with less indentation than this are the unloaded part of a
    #: press and are left out of F/delta (noise and offsets dominate there), mm.
    min_indentation_mm: float = 2.0
    #: Live estimate: at least this many loaded samples before a value is reported.
    min_samples: int = 5


# --------------------------------------------------------------------------- fitting


@dataclass(frozen=True)
class LinearFit:
    """F = k * delta through the origin, with its R^2 and sample count."""

    k_n_per_mm: float
    r2: float
    n: int


def fit_through_origin(indentation_mm: ArrayLike, force_n: ArrayLike) -> LinearFit:
    """Least-squares k of F = k * delta (the paper's linear model, no intercept).

    R^2 = 1 - SS_res / SS_tot with SS_tot about the mean force (the centred, stricter
    form: an uncentred R^2 would flatter a through-origin fit).
    """
    d = np.asarray(indentation_mm, np.float64).ravel()
    f = np.asarray(force_n, np.float64).ravel()
    if d.shape != f.shape:
        raise SoftnessError(f"indentation and force differ in length ({d.size} vs {f.size})")
    ok = np.isfinite(d) & np.isfinite(f)
    d, f = d[ok], f[ok]
    if d.size < 2:
        raise SoftnessError(f"a fit needs at least 2 finite samples, got {d.size}")
    sdd = float(d @ d)
    if sdd <= 0.0:
        raise SoftnessError("all indentations are zero: nothing to fit")
    k = float(d @ f) / sdd
    res = f - k * d
    ss_tot = float(((f - f.mean()) ** 2).sum())
    r2 = 1.0 - float(res @ res) / ss_tot if ss_tot > 0 else (1.0 if res @ res == 0 else 0.0)
    return LinearFit(k, r2, int(d.size))


# ----------------------------------------------------------------- the fabric's table


@dataclass
class SoftnessTable:
    """k(theta) of the fabric, fitted per motor position; inverted for rendering.

    ``theta_rad`` ascending. The inversion uses a monotonic version of k(theta)
    (``monotonic_k``: pool-adjacent-violators), so a noisy table still gives one motor
    position per stiffness.
    """

    theta_rad: NDArray[np.float64]
    k_n_per_mm: NDArray[np.float64]
    r2: NDArray[np.float64]
    n_samples: NDArray[np.int64]
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.theta_rad = np.asarray(self.theta_rad, np.float64)
        self.k_n_per_mm = np.asarray(self.k_n_per_mm, np.float64)
        self.r2 = np.asarray(self.r2, np.float64)
        self.n_samples = np.asarray(self.n_samples, np.int64)
        n = self.theta_rad.size
        if n < 2:
            raise SoftnessError(f"a softness table needs at least 2 motor positions, got {n}")
        if not (self.k_n_per_mm.size == self.r2.size == self.n_samples.size == n):
            raise SoftnessError("softness table columns differ in length")
        if np.any(np.diff(self.theta_rad) <= 0):
            raise SoftnessError("softness table: theta_rad must be strictly increasing")
        if not np.all(np.isfinite(self.k_n_per_mm)) or np.any(self.k_n_per_mm <= 0):
            raise SoftnessError("softness table: every k_n_per_mm must be positive")
        self._build_inverse()

    def _build_inverse(self) -> None:
        k = self.k_n_per_mm
        # The sense of k(theta) follows the motors' sign convention; take it from the data.
        self.increasing = bool(k[-1] >= k[0])
        signed = k if self.increasing else -k
        mono = _isotonic(signed, self.n_samples.astype(np.float64))
        self.monotonic_k = mono if self.increasing else -mono
        # Tied blocks (a flat stretch after pooling) become one point at their mean theta,
        # so the inverse is a function.
        ks, ths = [], []
        i = 0
        while i < mono.size:
            j = i
            while j + 1 < mono.size and mono[j + 1] == mono[i]:
                j += 1
            ks.append(mono[i])
            ths.append(float(self.theta_rad[i:j + 1].mean()))
            i = j + 1
        if len(ks) < 2:
            raise SoftnessError("softness table: k does not change with theta, cannot invert")
        self._inv_k = np.asarray(ks)  # ascending (signed)
        self._inv_theta = np.asarray(ths)

    @property
    def k_range_n_per_mm(self) -> tuple[float, float]:
        """The characterised stiffness range (after the monotonic fit)."""
        return float(self.monotonic_k.min()), float(self.monotonic_k.max())

    def stiffness_at(self, theta_rad: float) -> float:
        """k at a motor position, interpolated on the monotonic table."""
        return float(np.interp(theta_rad, self.theta_rad, self.monotonic_k))

    def theta_for(self, k_n_per_mm: float, strict: bool = False) -> float:
        """The motor position that renders ``k_n_per_mm`` (linear interpolation).

        Outside the characterised range: refused (``strict``) or clamped to its nearest
        end with a :class:`SoftnessWarning`.
        """
        k = float(k_n_per_mm)
        if not math.isfinite(k) or k <= 0:
            raise SoftnessError(f"requested stiffness {k_n_per_mm!r} N/mm is not positive")
        lo, hi = self.k_range_n_per_mm
        if k < lo or k > hi:
            msg = (f"requested stiffness {k:.3f} N/mm is outside the characterised range "
                   f"{lo:.3f}-{hi:.3f} N/mm")
            if strict:
                raise SoftnessError(msg)
            warnings.warn(f"{msg}: clamped to {min(max(k, lo), hi):.3f} N/mm",
                          SoftnessWarning, stacklevel=2)
            k = min(max(k, lo), hi)
        signed = k if self.increasing else -k
        return float(np.interp(signed, self._inv_k, self._inv_theta))


def _isotonic(y: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Weighted non-decreasing least-squares fit (pool adjacent violators)."""
    vals: list[float] = []
    wts: list[float] = []
    cnt: list[int] = []
    for yi, wi in zip(y, np.maximum(w, 1e-12), strict=True):
        vals.append(float(yi))
        wts.append(float(wi))
        cnt.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            wsum = wts[-2] + wts[-1]
            v = (vals[-2] * wts[-2] + vals[-1] * wts[-1]) / wsum
            c = cnt[-2] + cnt[-1]
            del vals[-1], wts[-1], cnt[-1]
            vals[-1], wts[-1], cnt[-1] = v, wsum, c
    return np.repeat(np.asarray(vals), cnt)


def characterise_fabric(
    theta_rad: ArrayLike, indentation_mm: ArrayLike, force_n: ArrayLike,
    config: SoftnessConfig = SoftnessConfig(), decimals: int = 6,
) -> SoftnessTable:
    """Fit k(theta) from indenter samples taken at several motor positions (Fig. 6).

    Samples are grouped by theta (rounded to ``decimals``); each group gets a
    through-origin fit and its R^2. Groups below ``config.r2_warn`` and a k(theta) that
    is not monotonic are reported in ``table.notes`` and as :class:`SoftnessWarning`.
    """
    th = np.round(np.asarray(theta_rad, np.float64).ravel(), decimals)
    d = np.asarray(indentation_mm, np.float64).ravel()
    f = np.asarray(force_n, np.float64).ravel()
    if not (th.size == d.size == f.size):
        raise SoftnessError("theta, indentation and force columns differ in length")
    groups = np.unique(th[np.isfinite(th)])
    if groups.size < 2:
        raise SoftnessError(
            f"the characterisation needs samples at 2 or more motor positions, got "
            f"{groups.size}")
    ks, r2s, ns, notes = [], [], [], []
    for g in groups:
        sel = th == g
        try:
            fit = fit_through_origin(d[sel], f[sel])
        except SoftnessError as exc:
            raise SoftnessError(f"theta_rad={g:g}: {exc}") from None
        if fit.k_n_per_mm <= 0:
            raise SoftnessError(f"theta_rad={g:g}: fitted k = {fit.k_n_per_mm:.4g} N/mm is "
                                "not positive (force and indentation signs?)")
        ks.append(fit.k_n_per_mm)
        r2s.append(fit.r2)
        ns.append(fit.n)
        if fit.r2 < config.r2_warn:
            notes.append(f"theta_rad={g:g}: R^2 = {fit.r2:.3f} is below {config.r2_warn} "
                         "(the paper's fits were all above): check the data")
    table = SoftnessTable(groups, np.asarray(ks), np.asarray(r2s), np.asarray(ns), notes)
    if np.any(np.abs(table.monotonic_k - table.k_n_per_mm) > 1e-12):
        bad = groups[np.abs(table.monotonic_k - table.k_n_per_mm) > 1e-12]
        notes.append("k(theta) is not monotonic at theta_rad = "
                     + ", ".join(f"{b:g}" for b in bad)
                     + ": the inversion uses a monotonic fit through them")
    for n in notes:
        warnings.warn(n, SoftnessWarning, stacklevel=2)
    return table


TABLE_COLUMNS = ("theta_rad", "k_n_per_mm", "r2", "n_samples")


def save_table(table: SoftnessTable, path: str | Path, source: str = "") -> Path:
    """Write the table CSV (``docs/softness.md``): a ``#`` comment line, then columns."""
    path = Path(path)
    lines = [f"# fydpad softness table{' from ' + source if source else ''}",
             ",".join(TABLE_COLUMNS)]
    for t, k, r2, n in zip(table.theta_rad, table.k_n_per_mm, table.r2, table.n_samples,
                           strict=True):
        lines.append(f"{t:.6f},{k:.6f},{r2:.6f},{int(n)}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def load_table(path: str | Path) -> SoftnessTable:
    """Read a table CSV; errors name the file (and line, column where it applies)."""
    # lazy: vision.recording loads OpenCV, and fydpad.config imports this module
    from vision.recording import RecordingError, read_csv_columns

    try:
        cols = read_csv_columns(path, ("theta_rad", "k_n_per_mm"), optional=("r2", "n_samples"))
    except RecordingError as exc:
        raise SoftnessError(str(exc)) from None
    n = cols["theta_rad"].size
    order = np.argsort(cols["theta_rad"], kind="stable")
    try:
        return SoftnessTable(
            cols["theta_rad"][order], cols["k_n_per_mm"][order],
            cols.get("r2", np.full(n, np.nan))[order],
            cols.get("n_samples", np.ones(n))[order].astype(np.int64),
        )
    except SoftnessError as exc:
        raise SoftnessError(f"{path}: {exc}") from None


# ----------------------------------------------------------------------- specimens


@dataclass(frozen=True)
class Specimen:
    """A characterised specimen (paper IV-A): stiffness lambda and grating roughness."""

    name: str
    lambda_n_per_mm: float
    #: Grating spatial period (ridge + groove), mm; 0 when smooth or unknown.
    period_mm: float = 0.0
    note: str = ""


#: The paper's four silicone specimens (section IV-A): S1 = 0.88 N/mm (SS1, SS2),
#: S2 = 0.39 N/mm (SS3, SS4); R1 = 3.90 mm period (SS1, SS3), R2 = 2.15 mm (SS2, SS4).
SPECIMENS: dict[str, Specimen] = {
    s.name: s for s in (
        Specimen("SS1", 0.88, 3.90, "S1 softness, R1 roughness"),
        Specimen("SS2", 0.88, 2.15, "S1 softness, R2 roughness"),
        Specimen("SS3", 0.39, 3.90, "S2 softness, R1 roughness"),
        Specimen("SS4", 0.39, 2.15, "S2 softness, R2 roughness"),
    )
}


def specimen(name: str, library: dict[str, Specimen] | None = None) -> Specimen:
    """A specimen by name (case-insensitive); an unknown name lists the known ones."""
    lib = SPECIMENS if library is None else library
    for key, s in lib.items():
        if key.lower() == name.strip().lower():
            return s
    raise SoftnessError(f"unknown specimen {name!r} (known: {', '.join(sorted(lib))})")


def fit_specimen(
    indentation_mm: ArrayLike, force_n: ArrayLike, name: str = "specimen",
    config: SoftnessConfig = SoftnessConfig(),
) -> tuple[Specimen, LinearFit, list[str]]:
    """lambda of F = lambda * delta from indenter data (paper IV-A), its fit and notes."""
    fit = fit_through_origin(indentation_mm, force_n)
    if fit.k_n_per_mm <= 0:
        raise SoftnessError(f"fitted lambda = {fit.k_n_per_mm:.4g} N/mm is not positive")
    notes = []
    if fit.r2 < config.specimen_r2_warn:
        notes.append(f"{name}: R^2 = {fit.r2:.3f} is below {config.specimen_r2_warn} "
                     "(the paper's specimen fits were all above)")
    for n in notes:
        warnings.warn(n, SoftnessWarning, stacklevel=2)
    return Specimen(name, fit.k_n_per_mm), fit, notes


# ------------------------------------------------------------------ live estimation


class LiveStiffness:
    """The stiffness the finger feels, F / delta over a press, from live streams.

    Feed one (force, indentation) sample at a time (``update``; no allocation). A press
    starts when the indentation rises above ``press_start_mm`` and ends below
    ``press_end_mm``. Within a press, only loaded samples (indentation >=
    ``min_indentation_mm`` and positive force) enter the through-origin fit
    k = sum(F delta) / sum(delta^2): near zero indentation the ratio is dominated by
    sensor noise and offsets. ``k_n_per_mm`` is the current press's estimate (NaN until
    ``min_samples`` loaded samples), ``last_k_n_per_mm`` the last finished press's.
    """

    def __init__(self, config: SoftnessConfig = SoftnessConfig()) -> None:
        self.config = config
        self.in_press = False
        self.presses = 0
        self.last_k_n_per_mm = math.nan
        #: The press that just ended (NaN when it had too few loaded samples).
        self.ended_k_n_per_mm = math.nan
        self._reset()

    def _reset(self) -> None:
        self._n = 0
        self._sdf = 0.0
        self._sdd = 0.0
        self._sff = 0.0
        self._sf = 0.0

    def update(self, force_n: float, indentation_mm: float) -> float:
        """Add a sample; returns the current estimate (NaN when there is none)."""
        c = self.config
        d = indentation_mm
        if not (d == d and force_n == force_n):  # NaN: a sensor gap, skip
            return self.k_n_per_mm
        if self.in_press:
            if d < c.press_end_mm:
                self.ended_k_n_per_mm = (self._sdf / self._sdd if self._n >= c.min_samples
                                         else math.nan)
                if self._n >= c.min_samples:
                    self.last_k_n_per_mm = self.ended_k_n_per_mm
                self.in_press = False
                self._reset()
                return self.last_k_n_per_mm
        elif d > c.press_start_mm:
            self.in_press = True
            self.presses += 1
            self._reset()
        if self.in_press and d >= c.min_indentation_mm and force_n > 0.0:
            self._n += 1
            self._sdf += force_n * d
            self._sdd += d * d
            self._sff += force_n * force_n
            self._sf += force_n
        return self.k_n_per_mm

    @property
    def k_n_per_mm(self) -> float:
        """This press's F/delta (least squares through the origin), else the last press's."""
        if self.in_press and self._n >= self.config.min_samples:
            return self._sdf / self._sdd
        return self.last_k_n_per_mm if not self.in_press else math.nan

    @property
    def r2(self) -> float:
        """R^2 of the current press's fit (centred), NaN without one."""
        if not self.in_press or self._n < self.config.min_samples:
            return math.nan
        k = self._sdf / self._sdd
        ss_res = self._sff - 2 * k * self._sdf + k * k * self._sdd
        ss_tot = self._sff - self._sf * self._sf / self._n
        return 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan


def stiffness_over_presses(
    force_n: Sequence[float] | NDArray, indentation_mm: Sequence[float] | NDArray,
    config: SoftnessConfig = SoftnessConfig(),
) -> list[float]:
    """F/delta of every complete press in two aligned streams (offline twin of LiveStiffness)."""
    est = LiveStiffness(config)
    out: list[float] = []
    for f, d in zip(np.asarray(force_n, float), np.asarray(indentation_mm, float), strict=True):
        was = est.in_press
        est.update(float(f), float(d))
        if was and not est.in_press:
            out.append(est.ended_k_n_per_mm)
    return out
