"""Beyond thesis 003: a network that predicts the texture's spectrum, not its samples.

The thesis network maps (v, Δf) to the acceleration sample by sample, so it can only
render what those inputs determine (docs/texture_mlp.md). This network predicts the
LPC model of eq. 5 instead: from (speed, force) to the line spectral frequencies and
the log residual variance of the texture near that state,

    h = tanh(W1 u + b1),   g = g_min + (pi - (p+1) g_min) softmax(W2 h + b2),
    LSF_k = sum_{j<=k} g_j,
    log sigma^2 = w3 . h + b3,

with p + 1 gaps of at least g_min = 1e-4 rad summing to pi, so the p LSFs are
strictly increasing in (0, pi) for any weights: in exact arithmetic every output is a
stable all-pole filter (``lsf.py``); in floating point, LSFs crowded within ~1e-3 rad
lose it at order 100-200, which fitted spectra never approach (smallest fitted gap
measured: 1.7e-3 rad).

Training data: per-window LPC fits (``fit.fit_speed``, the LPC family's own two-stage
fit) over 1 s windows (hop 0.5 s) of the preprocessed scans (10 Hz high-pass, DFT321)
whose speed is steady, labelled with the window's mean speed and force. Order 100 by
default: ten samples per coefficient in a 1 s window (order 200 on 1000 samples gives
noisy per-window LSFs; both are measured in docs/texture_mlp.md). Loss: mean squared
LSF error in units of the mean gap pi / (p + 1), plus the squared log-variance error;
full-batch Adam, deterministic per seed; the output biases start at the mean fitted
gaps and log-variance.

Rendering: the network is evaluated on a speed grid at one force and the result is
an ordinary speed-indexed ``TextureModel``, rendered by the LPC family's own path
(``TextureRenderer``: LSF interpolation, eq. 5). The renderer is indexed by speed
only, so force enters at a fixed value per render (a hook for force-indexed tables
would be needed to follow it live).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError
from fydpad.texture.dft321 import preprocess
from fydpad.texture.fit import fit_speed
from fydpad.texture.lpc import h_from_poly
from fydpad.texture.lsf import lsf_to_poly, poly_to_lsf
from fydpad.texture.model_file import TextureModel
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]
KIND = "mlp_lsf"
FORMAT = "fydpad-texture-model"
FORMAT_VERSION = 1
#: Every gap between neighbouring LSFs (and 0, pi) is at least this: softmax gaps can
#: underflow to 0 for extreme weights, and equal LSFs are not a stable filter.
MIN_GAP_RAD = 1e-4


# ------------------------------------------------------------------ training data
@dataclass
class WindowFits:
    """Per-window targets: speed (n,), force (n,), LSFs (n, p), log sigma^2 (n,)."""

    speed_mm_s: Array
    force_n: Array
    lsf: Array
    log_sigma2: Array


def window_fits(scans: Sequence[Scan], order: int = 100, window_s: float = 1.0,
                hop_s: float = 0.5, highpass_hz: float = 10.0, min_speed_mm_s: float = 3.0,
                max_speed_cv: float = 0.15, default_force_n: float = 1.0) -> WindowFits:
    """LPC of every window whose speed is steady (std / mean <= ``max_speed_cv``)."""
    sp, fo, ls, lv = [], [], [], []
    for scan in scans:
        x = preprocess(scan.acc, scan.fs_hz, highpass_hz)
        n = round(window_s * scan.fs_hz)
        hop = round(hop_s * scan.fs_hz)
        if n < 4 * order:
            raise UserError(f"{scan.path}: windows of {window_s:g} s hold {n} samples, an "
                            f"order-{order} fit needs {4 * order}; lower --order")
        force = scan.force_n if scan.force_n is not None else np.full(x.size, default_force_n)
        for a in range(0, x.size - n + 1, hop):
            v = scan.speed_mm_s[a:a + n]
            vm = float(np.mean(v))
            if vm < min_speed_mm_s or np.std(v) > max_speed_cv * vm:
                continue
            try:
                poly, s2 = fit_speed([x[a:a + n]], order)
                lsf = poly_to_lsf(poly)
            except ValueError:
                continue  # an unstable or unresolvable window: leave it out
            sp.append(vm)
            fo.append(float(np.mean(force[a:a + n])))
            ls.append(lsf)
            lv.append(math.log(s2))
    if not sp:
        raise UserError("no window of the scans has a steady speed to fit (column "
                        "'speed_mm_s')")
    return WindowFits(np.array(sp), np.array(fo), np.vstack(ls), np.array(lv))


# ------------------------------------------------------------------ network
@dataclass
class SpectrumNet:
    """(speed, force) -> (LSFs, log sigma^2); see the module docstring."""

    w1: Array  # (H, 2)
    b1: Array  # (H,)
    w2: Array  # (p + 1, H)
    b2: Array  # (p + 1,)
    w3: Array  # (H,)
    b3: float
    in_offset: Array  # (2,) speed, force
    in_scale: Array  # (2,)
    fs_hz: float = 1000.0
    highpass_hz: float = 10.0
    speed_range_mm_s: tuple[float, float] = (10.0, 40.0)
    surface: str = ""
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def order(self) -> int:
        return int(self.w2.shape[0] - 1)

    def _forward(self, u: Array) -> tuple[Array, Array, Array, Array]:
        h = np.tanh(u @ self.w1.T + self.b1)
        z = h @ self.w2.T + self.b2
        z -= z.max(axis=1, keepdims=True)
        s = np.exp(z)
        s /= s.sum(axis=1, keepdims=True)
        lsf = np.cumsum(MIN_GAP_RAD + self._span() * s, axis=1)[:, :-1]
        return h, s, lsf, h @ self.w3 + self.b3

    def _span(self) -> float:
        """pi less the p + 1 minimum gaps: the part of (0, pi) the softmax shares out."""
        return np.pi - (self.order + 1) * MIN_GAP_RAD

    def inputs(self, speed_mm_s: ArrayLike, force_n: ArrayLike) -> Array:
        x = np.column_stack(np.broadcast_arrays(np.ravel(speed_mm_s), np.ravel(force_n)))
        return (x - self.in_offset) * self.in_scale

    def predict(self, speed_mm_s: ArrayLike, force_n: ArrayLike = 1.0) -> tuple[Array, Array]:
        """LSFs (n, p) in rad and sigma^2 (n,) in (m/s^2)^2."""
        _, _, lsf, lv = self._forward(self.inputs(speed_mm_s, force_n))
        return lsf, np.exp(np.clip(lv, -700.0, 700.0))

    def texture_model(self, force_n: float = 1.0, step_mm_s: float = 1.0,
                      tolerance_mm_s: float = 5.0) -> TextureModel:
        """An ordinary speed-indexed LPC model: the network on a speed grid at one force."""
        lo, hi = self.speed_range_mm_s
        grid = np.arange(lo, hi + 0.5 * step_mm_s, step_mm_s)
        lsf, s2 = self.predict(grid, force_n)
        h = np.vstack([h_from_poly(lsf_to_poly(row)) for row in lsf])
        return TextureModel(self.surface, self.fs_hz, grid, h, s2, self.highpass_hz,
                            (self.highpass_hz, self.fs_hz / 2), None, 1.0, tolerance_mm_s,
                            {"kind": KIND, "force_n": force_n, **self.provenance})


@dataclass(frozen=True)
class SpectrumTrainConfig:
    hidden: int = 16
    iterations: int = 3000
    learning_rate: float = 0.01  # Adam
    weight_decay: float = 1e-4
    log_var_weight: float = 1.0
    seed: int = 0


def train_spectrum(fits: WindowFits, cfg: SpectrumTrainConfig = SpectrumTrainConfig(), *,
                   fs_hz: float = 1000.0, highpass_hz: float = 10.0,
                   surface: str = "") -> tuple[SpectrumNet, list[float]]:
    """Full-batch Adam on the per-window fits; returns the net and the loss history."""
    rng = np.random.default_rng(cfg.seed)
    x = np.column_stack([fits.speed_mm_s, fits.force_n])
    off = x.mean(axis=0)
    sd = x.std(axis=0)
    scale = np.where(sd > 1e-9, 1.0 / np.where(sd > 1e-9, sd, 1.0), 0.0)  # constant force: 0
    u = (x - off) * scale
    n, p = fits.lsf.shape
    gaps = np.diff(np.concatenate([np.zeros((n, 1)), fits.lsf, np.full((n, 1), np.pi)],
                                  axis=1))
    hdim = cfg.hidden
    net = SpectrumNet(
        rng.normal(0, 1.0, (hdim, 2)), rng.normal(0, 0.5, hdim),
        rng.normal(0, 0.1 / math.sqrt(hdim), (p + 1, hdim)),
        np.log(np.maximum(gaps.mean(axis=0), 1e-9)),
        rng.normal(0, 0.1 / math.sqrt(hdim), hdim), float(fits.log_sigma2.mean()),
        off, scale, fs_hz, highpass_hz,
        (float(fits.speed_mm_s.min()), float(fits.speed_mm_s.max())), surface)
    unit = np.pi / (p + 1)  # LSF errors in mean gaps
    names = ("w1", "b1", "w2", "b2", "w3")
    m = {k: np.zeros_like(getattr(net, k)) for k in names}
    v = {k: np.zeros_like(getattr(net, k)) for k in names}
    mb3 = vb3 = 0.0
    b1_, b2_, eps = 0.9, 0.999, 1e-8
    history = []
    for it in range(1, cfg.iterations + 1):
        h, s, lsf, lv = net._forward(u)
        el = (lsf - fits.lsf) / unit
        ev = lv - fits.log_sigma2
        history.append(float(np.mean(el * el) + cfg.log_var_weight * np.mean(ev * ev)))
        d_lsf = 2.0 * el / (unit * n * p)
        d_g = np.concatenate([np.cumsum(d_lsf[:, ::-1], axis=1)[:, ::-1],
                              np.zeros((n, 1))], axis=1)  # g_j feeds LSF_k for k >= j
        d_z = net._span() * s * (d_g - np.sum(s * d_g, axis=1, keepdims=True))
        d_lv = 2.0 * cfg.log_var_weight * ev / n
        d_h = d_z @ net.w2 + np.outer(d_lv, net.w3)
        d_a = d_h * (1.0 - h * h)
        grads = {"w1": d_a.T @ u, "b1": d_a.sum(axis=0), "w2": d_z.T @ h,
                 "b2": d_z.sum(axis=0), "w3": h.T @ d_lv}
        for k in ("w1", "w2", "w3"):
            grads[k] = grads[k] + cfg.weight_decay * getattr(net, k)
        c1, c2 = 1.0 - b1_ ** it, 1.0 - b2_ ** it
        for k in names:
            m[k] = b1_ * m[k] + (1 - b1_) * grads[k]
            v[k] = b2_ * v[k] + (1 - b2_) * grads[k] ** 2
            getattr(net, k)[...] -= cfg.learning_rate * (m[k] / c1) / (np.sqrt(v[k] / c2) + eps)
        gb3 = float(d_lv.sum())
        mb3 = b1_ * mb3 + (1 - b1_) * gb3
        vb3 = b2_ * vb3 + (1 - b2_) * gb3 * gb3
        net.b3 -= cfg.learning_rate * (mb3 / c1) / (math.sqrt(vb3 / c2) + eps)
    net.provenance = {"training": asdict(cfg), "windows": int(n), "final_loss": history[-1]}
    return net, history


def fit_spectrum_net(scans: Sequence[Scan], *, order: int = 100, window_s: float = 1.0,
                     cfg: SpectrumTrainConfig = SpectrumTrainConfig(),
                     surface: str | None = None) -> SpectrumNet:
    scans = list(scans)
    if not scans:
        raise UserError("no scans to fit")
    fits = window_fits(scans, order, window_s)
    net, _ = train_spectrum(fits, cfg, fs_hz=scans[0].fs_hz, surface=surface or scans[0].surface)
    net.provenance.update({"scans": [s.path for s in scans], "order": order,
                           "window_s": window_s, "tool": "fydpad texture fit --kind mlp_lsf",
                           "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")})
    return net


# ------------------------------------------------------------------ model file
def net_to_json(net: SpectrumNet) -> dict[str, Any]:
    def lst(a: Array) -> list:
        return np.asarray(a, float).tolist()

    return {
        "format": FORMAT, "kind": KIND, "format_version": FORMAT_VERSION,
        "surface": net.surface, "sample_rate_hz": net.fs_hz, "order": net.order,
        "highpass_hz": net.highpass_hz, "speed_range_mm_s": list(net.speed_range_mm_s),
        "inputs": ["speed_mm_s", "force_n"],
        "outputs": "LSF_k = cumsum(g_min + (pi - (p + 1) g_min) softmax(w2 tanh(w1 u + b1) "
                   "+ b2))[k], g_min = 1e-4 rad; "
                   "log sigma2 = w3 . tanh(w1 u + b1) + b3; u = (x - input_offset) * input_scale",
        "weights": {"w1": lst(net.w1), "b1": lst(net.b1), "w2": lst(net.w2), "b2": lst(net.b2),
                    "w3": lst(net.w3), "b3": float(net.b3)},
        "input_offset": lst(net.in_offset), "input_scale": lst(net.in_scale),
        "units": {"sigma2": "(m/s^2)^2", "lsf": "rad"},
        "provenance": net.provenance,
    }


def save_spectrum_net(net: SpectrumNet, path: str | Path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(net_to_json(net)) + "\n", encoding="utf-8")
    return path


def parse_spectrum_net(data: Any, where: str = "model") -> SpectrumNet:
    """Check and convert a parsed network; errors name the file and the key."""
    from fydpad.texture.families.mlp.model import _key, _vector

    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UserError(f"{where}: not a fydpad texture model (key 'format' must be '{FORMAT}')")
    if data.get("kind") != KIND or data.get("format_version") != FORMAT_VERSION:
        got = f"{data.get('kind')!r}/{data.get('format_version')!r}"
        raise UserError(f"{where}: keys 'kind'/'format_version' must be '{KIND}'/"
                        f"{FORMAT_VERSION}, got {got}")
    w = _key(data, "weights", where)
    ww = f"{where}: weights"
    b1 = np.asarray(_key(w, "b1", ww), dtype=object)
    b2 = np.asarray(_key(w, "b2", ww), dtype=object)
    hdim, q = b1.size, b2.size
    if hdim < 1 or q < 2:
        raise UserError(f"{ww}: keys 'b1'/'b2' must list the hidden units and p + 1 gaps")
    lo_hi = _vector(data, "speed_range_mm_s", where, (2,))
    if not 0 < lo_hi[0] <= lo_hi[1]:
        raise UserError(f"{where}: key 'speed_range_mm_s' must be increasing and positive")
    fs = float(_vector(data, "sample_rate_hz", where, ()))
    if not fs > 0:
        raise UserError(f"{where}: key 'sample_rate_hz' must be positive")
    return SpectrumNet(
        _vector(w, "w1", ww, (hdim, 2)), _vector(w, "b1", ww, (hdim,)),
        _vector(w, "w2", ww, (q, hdim)), _vector(w, "b2", ww, (q,)),
        _vector(w, "w3", ww, (hdim,)), float(_vector(w, "b3", ww, ())),
        _vector(data, "input_offset", where, (2,)), _vector(data, "input_scale", where, (2,)),
        fs, float(data.get("highpass_hz", 10.0)), (float(lo_hi[0]), float(lo_hi[1])),
        str(data.get("surface", "")), dict(data.get("provenance", {})))


def load_spectrum_net(path: str | Path) -> SpectrumNet:
    from fydpad.texture.families import read_model_json

    return parse_spectrum_net(read_model_json(path), str(path))


# ------------------------------------------------------------------ family
def family_from_net(net: SpectrumNet, path: str | None = None, force_n: float = 1.0) -> Any:
    """The LPC family's renderer (``LpcFamily``) on the network's speed table."""
    from fydpad.texture.families import LpcFamily

    # Its speed table is dense, and its figures (mlp_eval) were measured with "lsf".
    fam = LpcFamily(net.texture_model(force_n), path, method="lsf")
    fam.kind = KIND  # type: ignore[misc]
    return fam


def _family_from_json(data: dict[str, Any], where: str) -> Any:
    return family_from_net(parse_spectrum_net(data, where), where)


def _fit_json(scans: list, **options: Any) -> dict[str, Any]:
    """``fit_family("mlp_lsf", scans, order=.., window_s=.., seed=.., iterations=..)``."""
    from dataclasses import fields

    names = {f.name for f in fields(SpectrumTrainConfig)}
    top = {k: options.pop(k) for k in ("order", "window_s", "surface") if k in options}
    bad = sorted(set(options) - names)
    if bad:
        raise UserError(f"mlp_lsf fit: unknown option(s) {', '.join(bad)} (known: "
                        f"{', '.join(sorted(names | {'order', 'window_s', 'surface'}))})")
    return net_to_json(fit_spectrum_net(scans, cfg=SpectrumTrainConfig(**options), **top))
