"""Training the thesis' 3-10-1 texture network (Lin 2016, section 3.2, Fig. 3.18): the
data pipeline and the settings (``TrainConfig``, defaults the thesis') are tabled in
docs/texture_mlp.md.
"""

from __future__ import annotations

import copy
import datetime as _dt
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.texture.families.mlp.model import (
    BAND_HZ,
    DF_TAU_S,
    MlpModel,
    MlpNet,
    Scaling,
    bandpass_fft,
    delta_force,
    logsig,
    velocity_xy,
)
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TrainConfig:
    """Thesis 3.2 training settings (Table 3.1 and the text after Fig. 3.18)."""

    hidden: int = 10
    init_range: float = 10.0
    learning_rate: float = 0.9
    max_epochs: int = 2000
    goal_mse: float = 1e-9
    max_fail: int = 6  # validation epochs without improvement (MATLAB default)
    mode: str = "online"  # "online" (thesis Fig. 3.18) or "batch"
    seed: int = 0


@dataclass
class TrainReport:
    epochs: int
    best_epoch: int
    stop: str  # "max_epochs", "goal", "validation", "diverged"
    train_mse: list[float]
    val_mse: list[float]


def init_net(n_in: int, cfg: TrainConfig) -> MlpNet:
    """All weights and biases uniform in [-init_range, init_range], from ``cfg.seed``."""
    rng = np.random.default_rng(cfg.seed)
    r = cfg.init_range
    return MlpNet(rng.uniform(-r, r, (cfg.hidden, n_in)), rng.uniform(-r, r, cfg.hidden),
                  rng.uniform(-r, r, cfg.hidden), float(rng.uniform(-r, r)))


def _online_epoch(net: MlpNet, u: Array, t: Array, lr: float) -> None:
    """One pass of per-sample steepest descent on e^2 / 2, in place, in time order."""
    w_in, b_in, w_out, b_out = net.w_in.tolist(), net.b_in.tolist(), net.w_out.tolist(), net.b_out
    hid, tanh, h = range(len(b_in)), math.tanh, [0.0] * len(b_in)
    for (u0, u1, u2), tk in zip(u.tolist(), t.tolist(), strict=True):
        y = b_out
        for j in hid:
            w = w_in[j]
            hj = 0.5 + 0.5 * tanh(0.5 * (w[0] * u0 + w[1] * u1 + w[2] * u2 + b_in[j]))
            h[j] = hj
            y += w_out[j] * hj
        e = lr * (tk - y)
        b_out += e
        for j in hid:
            hj = h[j]
            d = e * w_out[j] * hj * (1.0 - hj)  # uses the output weight before its update
            w_out[j] += e * hj
            w = w_in[j]
            w[0] += d * u0
            w[1] += d * u1
            w[2] += d * u2
            b_in[j] += d
    net.w_in[:], net.b_in[:], net.w_out[:], net.b_out = w_in, b_in, w_out, b_out


def _batch_epoch(net: MlpNet, u: Array, t: Array, lr: float) -> None:
    """One full-batch steepest-descent step on mean(e^2) / 2, in place."""
    h = logsig(u @ net.w_in.T + net.b_in)
    e = t - (h @ net.w_out + net.b_out)
    n = t.size
    d = (e[:, None] * net.w_out) * h * (1.0 - h)
    net.b_out += lr * float(e.sum()) / n
    net.w_out += lr * (e @ h) / n
    net.w_in += lr * (d.T @ u) / n
    net.b_in += lr * d.sum(axis=0) / n


def train(u_train: Array, t_train: Array, u_val: Array | None, t_val: Array | None,
          cfg: TrainConfig = TrainConfig()) -> tuple[MlpNet, TrainReport]:
    """Train on network-unit data (inputs (n, n_in), target (n,)); deterministic per seed."""
    if cfg.mode not in ("online", "batch"):
        raise UserError(f"mlp fit: option mode must be 'online' or 'batch', not {cfg.mode!r}")
    u_train, t_train = np.asarray(u_train, float), np.asarray(t_train, float)
    net = init_net(u_train.shape[1], cfg)
    step = _online_epoch if cfg.mode == "online" else _batch_epoch

    def mse(u: Array, t: Array) -> float:
        return float(np.mean((t - net.forward(u)) ** 2))

    have_val = u_val is not None and t_val is not None and len(t_val) > 0
    best, best_val, best_epoch, fails = copy.deepcopy(net), math.inf, 0, 0
    tr_hist, va_hist, stop, epoch = [], [], "max_epochs", 0
    for epoch in range(1, cfg.max_epochs + 1):
        step(net, u_train, t_train, cfg.learning_rate)
        if not (np.isfinite(net.w_in).all() and np.isfinite(net.w_out).all()
                and math.isfinite(net.b_out)):
            stop = "diverged"
            break
        tr_hist.append(tr := mse(u_train, t_train))
        va_hist.append(va := mse(u_val, t_val) if have_val else tr)
        if va < best_val:
            best, best_val, best_epoch, fails = copy.deepcopy(net), va, epoch, 0
        else:
            fails += 1
        if tr < cfg.goal_mse:
            stop = "goal"
            break
        if have_val and fails >= cfg.max_fail:
            stop = "validation"
            break
    if stop == "diverged" and best_epoch == 0:
        raise UserError(f"the network diverged in its first epoch (learning rate "
                        f"{cfg.learning_rate:g}, per sample); lower it (fit option "
                        "learning_rate, e.g. 0.3) or train with mode=batch")
    return best, TrainReport(epoch, best_epoch, stop, tr_hist, va_hist)


@dataclass
class Features:
    """Per-sample inputs (n, 3) = (v_x, v_y, Δf) and the band-passed target (n,)."""

    x: Array
    y: Array


def scan_features(scan: Scan, band_hz: tuple[float, float] = BAND_HZ,
                  df_tau_s: float = DF_TAU_S) -> Features:
    """Inputs and the band-passed z acceleration of a whole scan (needs ``force_n``)."""
    if scan.force_n is None:
        raise UserError(f"{scan.path}: column 'force_n' is missing or has empty cells: the "
                        "network's Δf input needs the normal force")
    df, _ = delta_force(scan.force_n, scan.fs_hz, df_tau_s)
    # A scan's stroke runs along x (+x without a position column).
    if scan.x_mm is None:
        vx, vy = scan.speed_mm_s, np.zeros_like(scan.speed_mm_s)
    else:
        vx, vy, _ = velocity_xy(scan.x_mm, np.zeros_like(scan.x_mm), scan.speed_mm_s)
    az = bandpass_fft(scan.acc[:, 2], scan.fs_hz, band_hz)
    return Features(np.column_stack([vx, vy, df]), az)


def thirds(n: int) -> tuple[slice, slice, slice]:
    """Contiguous thirds in time: training, validation, test (thesis 3.2)."""
    a, b = n // 3, 2 * n // 3
    return slice(0, a), slice(a, b), slice(b, n)


def fit_mlp(scans: Sequence[Scan], cfg: TrainConfig = TrainConfig(), *,
            surface: str | None = None
            ) -> tuple[MlpModel, TrainReport, tuple[Features, Features, Features]]:
    """Fit on the scans' first thirds, validate on the second; also return the split."""
    fs = scans[0].fs_hz
    for s in scans:
        if abs(s.fs_hz - fs) > 1e-6 * fs:
            raise UserError(f"{s.path}: column 't_s': sample rate {s.fs_hz:g} Hz differs "
                            f"from the first scan's {fs:g} Hz")
        if s.t_s.size < 30:
            raise UserError(f"{s.path}: only {s.t_s.size} samples; need 30 for three thirds")
    feats = [scan_features(s) for s in scans]
    # Each scan's thirds, pooled over the scans (so every speed is in every set).
    tr, va, te = (Features(np.vstack([f.x[thirds(f.y.size)[k]] for f in feats]),
                           np.concatenate([f.y[thirds(f.y.size)[k]] for f in feats]))
                  for k in range(3))
    scaling = Scaling.mapminmax(tr.x, tr.y)
    net, report = train(scaling.inputs(tr.x), scaling.target(tr.y),
                        scaling.inputs(va.x), scaling.target(va.y), cfg)
    model = MlpModel(net, scaling, fs, BAND_HZ, DF_TAU_S, surface or scans[0].surface,
                     {"scans": [s.path for s in scans], "tool": "fydpad texture fit --kind mlp",
                      "split": "contiguous thirds per scan: train, validation, test",
                      "training": asdict(cfg), "epochs": report.epochs,
                      "best_epoch": report.best_epoch, "stop": report.stop,
                      "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")})
    return model, report, (tr, va, te)
