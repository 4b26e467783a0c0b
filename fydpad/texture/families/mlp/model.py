"""The texture network of Lin 2016 (section 3.2, Tables 3.1-3.4): features, weights, file.

    net_j = logsig(sum_i w_in[j, i] u_i + b_in[j])        (eq. 4, 6; 10 hidden units)
    a_z   = sum_j w_out[j] net_j + b_out                    (eq. 5, 7; purelin)

with u = scale((v_x, v_y, Δf)), a_z unscaled; Δf and (v_x, v_y) as docs/texture_mlp.md defines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal as ss
from numpy.typing import ArrayLike, NDArray

from fydpad.errors import UserError
from fydpad.texture.family import FORMAT, read_model_json, require, require_version

Array = NDArray[np.float64]
KIND = "mlp"
FORMAT_VERSION = 1
BAND_HZ = (5.0, 500.0)  # thesis 3.2: hand jitter below 5 Hz, insensitivity above 500 Hz
DF_TAU_S = 0.05
INPUTS = ("vx_mm_s", "vy_mm_s", "df_n")
#: Above this a model file's rate is an error, not a texture (the audio channel is 48 kHz).
MAX_RATE_HZ = 1e6
THESIS_MODEL = Path(__file__).resolve().parents[2] / "data" / "thesis_mlp.json"


def bandpass_fft(x: ArrayLike, fs_hz: float, band_hz: tuple[float, float] = BAND_HZ) -> Array:
    """Thesis 3.2: DFT, zero every bin outside ``band_hz`` (inclusive), inverse DFT."""
    x = np.asarray(x, float)
    spec = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1.0 / fs_hz)
    spec[(f < band_hz[0]) | (f > band_hz[1])] = 0.0
    return np.fft.irfft(spec, x.size)


def delta_force(force_n: ArrayLike, fs_hz: float, tau_s: float = DF_TAU_S,
                mean_n: float | None = None) -> tuple[Array, float]:
    """Δf(k) = f(k) - m(k-1), m(k) = m(k-1) + alpha Δf(k), alpha = 1 - exp(-1/(tau fs));
    ``mean_n`` carried from the previous block (None: the first force). -> (Δf, mean)."""
    f = np.asarray(force_n, float)
    alpha = 1.0 - math.exp(-1.0 / (tau_s * fs_hz))
    m0 = float(f[0]) if mean_n is None else float(mean_n)
    m, _ = ss.lfilter([alpha], [1.0, alpha - 1.0], f, zi=[(1.0 - alpha) * m0])
    return f - np.concatenate([[m0], m[:-1]]), float(m[-1])


def velocity_xy(x_mm: ArrayLike, y_mm: ArrayLike, speed_mm_s: ArrayLike,
                last: tuple[float, float, float] = (math.nan, math.nan, 0.0)
                ) -> tuple[Array, Array, tuple[float, float, float]]:
    """(v_x, v_y) = speed (cos, sin) of the last position change's direction; ``last`` =
    (x, y, direction) carried from the previous block (0 rad until the finger moves)."""
    x, y, v = np.asarray(x_mm, float), np.asarray(y_mm, float), np.asarray(speed_mm_s, float)
    dx = x - np.concatenate([[last[0]], x[:-1]])
    dy = y - np.concatenate([[last[1]], y[:-1]])
    moved = np.isfinite(dx) & np.isfinite(dy) & ((dx != 0) | (dy != 0))
    ang = np.where(moved, np.arctan2(dy, dx), np.nan)
    idx = np.where(moved, np.arange(x.size), -1)  # forward-fill the last move's direction
    np.maximum.accumulate(idx, out=idx)
    theta = np.where(idx >= 0, ang[np.maximum(idx, 0)], last[2])
    return v * np.cos(theta), v * np.sin(theta), (float(x[-1]), float(y[-1]), float(theta[-1]))


def logsig(z: Array) -> Array:
    """1 / (1 + exp(-z)) without overflow warnings (thesis eq. 4)."""
    return 0.5 * (1.0 + np.tanh(0.5 * z))


@dataclass
class MlpNet:
    """Weights of an n_in-H-1 network (logsig hidden, purelin output), network units."""

    w_in: Array  # (H, n_in)
    b_in: Array  # (H,)
    w_out: Array  # (H,)
    b_out: float

    def forward(self, u: ArrayLike) -> Array:
        """Outputs for inputs ``u`` of shape (n, n_in): eq. 4-7."""
        return logsig(np.asarray(u, float) @ self.w_in.T + self.b_in) @ self.w_out + self.b_out


@dataclass
class Scaling:
    """u = (x - in_offset) * in_scale; y = out_offset + out_scale * net(u). Trained with
    MATLAB's default ``mapminmax`` (each input and the target to [-1, 1] by their training
    min and max); the thesis does not state its scaling."""

    in_offset: Array
    in_scale: Array
    out_offset: float = 0.0
    out_scale: float = 1.0
    method: str = "mapminmax"
    known: bool = True

    @classmethod
    def mapminmax(cls, x: Array, y: Array) -> Scaling:
        lo, hi = x.min(axis=0), x.max(axis=0)
        span = np.where(hi > lo, hi - lo, 1.0)  # a constant input maps to 0
        ylo, yhi = float(y.min()), float(y.max())
        return cls(0.5 * (lo + hi), 2.0 / span, 0.5 * (ylo + yhi),
                   0.5 * (yhi - ylo) if yhi > ylo else 1.0)

    def inputs(self, x: ArrayLike) -> Array:
        return (np.asarray(x, float) - self.in_offset) * self.in_scale

    def target(self, y: ArrayLike) -> Array:
        return (np.asarray(y, float) - self.out_offset) / self.out_scale


@dataclass
class MlpModel:
    """A thesis-style texture network with its input/output scaling and data settings."""

    net: MlpNet
    scaling: Scaling
    fs_hz: float = 1000.0
    band_hz: tuple[float, float] = BAND_HZ
    df_tau_s: float = DF_TAU_S
    surface: str = ""
    provenance: dict[str, Any] = field(default_factory=dict)


def model_to_json(model: MlpModel) -> dict[str, Any]:
    s, net = model.scaling, model.net
    return {
        "format": FORMAT, "kind": KIND, "format_version": FORMAT_VERSION,
        "surface": model.surface, "sample_rate_hz": model.fs_hz, "inputs": list(INPUTS),
        "output": "az_m_s2",  # the accelerometer axis normal to the surface (thesis 3.1)
        "hidden_activation": "logsig", "output_activation": "purelin",
        "band_hz": list(model.band_hz),
        "delta_force": {"definition": "force_n minus its causal exponential moving mean",
                        "tau_s": model.df_tau_s},
        "weights": {"input": net.w_in.tolist(), "input_bias": net.b_in.tolist(),
                    "output": net.w_out.tolist(), "output_bias": float(net.b_out)},
        "scaling": {
            "method": s.method, "known": s.known,
            "input_offset": s.in_offset.tolist(), "input_scale": s.in_scale.tolist(),
            "output_offset": float(s.out_offset), "output_scale": float(s.out_scale),
            "convention": "u = (x - input_offset) * input_scale; "
                          "y = output_offset + output_scale * net(u)",
        },
        "provenance": model.provenance,
    }


def _vector(d: Any, key: str, where: str, shape: tuple[int, ...]) -> Array:
    try:
        a = np.asarray(require(d, key, where, object), float)
    except (TypeError, ValueError):
        raise UserError(f"{where}: key '{key}' must be numbers") from None
    if a.shape != shape:
        raise UserError(f"{where}: key '{key}' has shape {a.shape}, expected {shape}")
    if not np.isfinite(a).all():
        raise UserError(f"{where}: key '{key}' is not finite")
    return a


def parse_mlp(data: dict[str, Any], where: str = "model") -> MlpModel:
    """Check and convert a parsed model file; errors name the file and the key."""
    require_version(data, where, KIND, FORMAT_VERSION)
    if data.get("inputs", list(INPUTS)) != list(INPUTS):
        raise UserError(f"{where}: key 'inputs' must be {list(INPUTS)}")
    w, ww = require(data, "weights", where, dict), f"{where}: weights"
    hidden = len(require(w, "input", ww, list))
    if hidden < 1:
        raise UserError(f"{where}: key 'weights.input' must list one row per hidden unit")
    net = MlpNet(_vector(w, "input", ww, (hidden, len(INPUTS))),
                 _vector(w, "input_bias", ww, (hidden,)), _vector(w, "output", ww, (hidden,)),
                 float(_vector(w, "output_bias", ww, ())))
    sc, sw = require(data, "scaling", where, dict), f"{where}: scaling"
    scaling = Scaling(_vector(sc, "input_offset", sw, (len(INPUTS),)),
                      _vector(sc, "input_scale", sw, (len(INPUTS),)),
                      float(_vector(sc, "output_offset", sw, ())),
                      float(_vector(sc, "output_scale", sw, ())),
                      str(sc.get("method", "")), bool(sc.get("known", True)))
    fs = float(_vector(data, "sample_rate_hz", where, ()))
    band = _vector(data, "band_hz", where, (2,))
    if not (0 < fs <= MAX_RATE_HZ and 0 <= band[0] < band[1]):
        raise UserError(f"{where}: keys 'sample_rate_hz'/'band_hz' must be positive and "
                        f"ordered, the rate at most {MAX_RATE_HZ:g} Hz (got {fs:g} Hz, "
                        f"{band.tolist()})")
    df = require(data, "delta_force", where, dict)
    tau = float(_vector(df, "tau_s", f"{where}: delta_force", ()))
    if not tau > 0:
        raise UserError(f"{where}: key 'delta_force.tau_s' must be positive, got {tau:g}")
    return MlpModel(net, scaling, fs, (float(band[0]), float(band[1])), tau,
                    str(data.get("surface", "")), dict(data.get("provenance", {})))


def thesis_model() -> MlpModel:
    """The thesis' trained weights (Tables 3.2-3.4, output bias 0.11); see its file."""
    return parse_mlp(read_model_json(THESIS_MODEL), str(THESIS_MODEL))
