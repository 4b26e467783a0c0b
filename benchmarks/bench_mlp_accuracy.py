"""Accuracy of the network of Lin 2016 against the LPC family (the baseline, measured
in the same run) on held-out data: the figures of docs/texture_mlp.md.

``python benchmarks/bench_mlp_accuracy.py`` prints the table (about 3 minutes);
``--plot DIR`` draws the spectra; ``--identify`` gives the network's identification
rates (``fydpad.texture.evaluation.identify``).

The thesis network (fit_mlp) and the LPC family on the test thirds of the same strokes,
both modelling the z acceleration: R^2 (sample by sample), the power-spectrum
correlation and the log-spectral distance (``evaluate.compare``). The LPC family here
is Bianchi 2015's method read plainly (``fit_paper``: an LPC per speed, no interpolation).

Force: the generator's own ``force_n`` (``friction=True``); for comparison also
``synthetic_force``, whose load follows the surface profile (the network's best case).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from fydpad.synth.texture_scans import DX_MM, TEXTURES, generate_scan, surface_profile
from fydpad.texture.evaluation.evaluate import compare
from fydpad.texture.families.mlp.render import MlpTexture
from fydpad.texture.families.mlp.train import TrainConfig, fit_mlp, scan_features, thirds
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.fit import fit_paper
from fydpad.texture.scan_io import Scan

Array = NDArray[np.float64]
SPEEDS = (10.0, 20.0, 30.0, 40.0)
TEXTURES_EVAL = ("R1", "R2", "felt", "glass")
_PROFILES: dict[str, Array] = {}


def synthetic_force(scan: Scan, *, preload_n: float = 1.0, sway_n: float = 0.3,
                    finger_n_mm: float = 1.5, noise_n: float = 0.005,
                    full_scale_n: float = 10.0, bits: int = 10, seed: int = 0) -> Array:
    """A force-sensor trace for a generated scan: what an FSR under the finger reads.

    f = preload + slow sway (< 1 Hz) + finger stiffness * h(x(t)) + white noise, then
    quantised like the thesis' 10-bit ADC over 10 N. h is the same surface profile the
    generator's tip follows (so force and acceleration share the texture's phase).
    """
    name = scan.meta.get("surface", "")
    if name not in TEXTURES or getattr(scan, "x_mm", None) is None:
        raise ValueError(f"{scan.path}: synthetic force needs a generated scan (surface, x_mm)")
    if name not in _PROFILES:
        _PROFILES[name] = surface_profile(TEXTURES[name])
    prof = _PROFILES[name]
    rng = np.random.default_rng([seed, 0xF0 + len(scan.t_s)])
    n = scan.t_s.size
    slow = ss.sosfiltfilt(ss.butter(2, 1.0, fs=scan.fs_hz, output="sos"), rng.standard_normal(n))
    slow *= sway_n / (np.std(slow) + 1e-12)
    h = np.interp(scan.x_mm / DX_MM, np.arange(prof.size), prof)  # type: ignore[attr-defined]
    f = preload_n + slow + finger_n_mm * (h - h.mean()) + noise_n * rng.standard_normal(n)
    q = full_scale_n / 2 ** bits
    return np.clip(np.round(f / q) * q, 0.0, full_scale_n)


def stroke(texture: str, speed: float, seconds: float, seed: int,
           force: str = "generator") -> Scan:
    """A generated stroke with a force column: the generator's own (``friction=True``: a
    hand's varying load plus sensor noise, independent of the profile) or ``"profile"``
    (:func:`synthetic_force`: the load also follows h(x), the network's best case)."""
    if force == "generator":
        return generate_scan(texture, speed, seconds, seed=seed, friction=True)
    if force != "profile":
        raise ValueError(f"force must be 'generator' or 'profile', not {force!r}")
    scan = generate_scan(texture, speed, seconds, seed=seed)
    scan.force_n = synthetic_force(scan, seed=seed)
    return scan


def _third(scan: Scan, k: int, z_only: bool = False) -> Scan:
    s = thirds(scan.t_s.size)[k]
    acc = scan.acc[s]
    if z_only:  # DFT321 of (0, 0, az) is az: the LPC family then models az as well
        acc = np.column_stack([np.zeros((acc.shape[0], 2)), acc[:, 2]])
    out = replace(scan, t_s=scan.t_s[s], acc=acc, speed_mm_s=scan.speed_mm_s[s],
                  force_n=None if scan.force_n is None else scan.force_n[s])
    out.x_mm = scan.x_mm[s]  # type: ignore[attr-defined]
    return out


def r_squared(target: Array, prediction: Array) -> float:
    """1 - SS_res / SS_tot: 0 for predicting the mean, negative for worse."""
    res = np.sum((target - prediction) ** 2)
    tot = np.sum((target - target.mean()) ** 2)
    return float(1.0 - res / tot)


def thesis_vs_lpc(texture: str, cfg: TrainConfig | None = None, seconds: float = 12.0,
                  speeds: Sequence[float] = SPEEDS, force: str = "generator"
                  ) -> dict[str, float | str]:
    """R^2, spectral correlation and LSD of both families on the strokes' test thirds."""
    from fydpad.texture.family import finger_from_scan

    cfg = cfg or TrainConfig()
    scans = [stroke(texture, s, seconds, seed=1, force=force) for s in speeds]
    try:
        model, report, (tr, _va, te) = fit_mlp(scans, cfg)
    except UserError:
        return {"texture": texture, "stop": "diverged"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lpc = fit_paper([_third(s, 0, z_only=True) for s in scans])
    rec_all, net_all, lpc_all, mask_all = [], [], [], []
    m_net, m_lpc = [], []
    for i, scan in enumerate(scans):
        feats = scan_features(scan, model.band_hz, model.df_tau_s)
        s = thirds(scan.t_s.size)[2]
        rec = feats.y[s]
        net = MlpTexture(model).render(finger_from_scan(scan))[s]
        test = _third(scan, 2)
        lpc_sig = _synth(lpc, test.speed_mm_s, seed=10 + i)
        mask = LpcFamily(lpc).covers(test.speed_mm_s)
        m_net.append(compare(rec, net, scan.fs_hz, mask)[0])
        m_lpc.append(compare(rec, lpc_sig, scan.fs_hz, mask)[0])
        rec_all.append(rec[mask])
        net_all.append(net[mask])
        lpc_all.append(lpc_sig[mask])
        mask_all.append(mask)
    rec_c = np.concatenate(rec_all)
    # What any function of these inputs could reach linearly: least squares on the test
    # third itself (an optimistic ceiling for R^2 from (v, df)).
    a = np.column_stack([np.ones(te.y.size), te.x, te.x[:, 2] * te.x[:, 0]])
    coef, *_ = np.linalg.lstsq(a, te.y, rcond=None)
    return {
        "texture": texture, "stop": report.stop, "epochs": report.epochs,
        "r2_mlp": r_squared(rec_c, np.concatenate(net_all)),
        "r2_lpc": r_squared(rec_c, np.concatenate(lpc_all)),
        "r2_linear_ceiling": r_squared(te.y, a @ coef),
        "corr_mlp": float(np.mean([c.psd_correlation for c in m_net])),
        "corr_lpc": float(np.mean([c.psd_correlation for c in m_lpc])),
        "lsd_mlp": float(np.mean([c.lsd_db for c in m_net])),
        "lsd_lpc": float(np.mean([c.lsd_db for c in m_lpc])),
        "rms_ratio_mlp": float(np.std(np.concatenate(net_all)) / np.std(rec_c)),
        "train_samples": int(tr.y.size),
    }


def _synth(model, speed: Array, seed: int) -> Array:
    from fydpad.texture.lpc.synthesis import synthesize

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return synthesize(model, speed, seed=seed)


def plot_figures(out_dir: str) -> list[str]:
    """The spectra of ``mlp_thesis_felt.png``: recorded against each family's."""
    from pathlib import Path

    from fydpad.texture.evaluation.evaluate import welch_psd
    from fydpad.texture.family import finger_from_scan
    from fydpad.texture.plots import plot_spectra

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scans = [stroke("felt", s, 12.0, seed=1, force="profile") for s in SPEEDS]
    model, _, _ = fit_mlp(scans, TrainConfig())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lpc = fit_paper([_third(s, 0, z_only=True) for s in scans])
    scan = scans[1]
    s = thirds(scan.t_s.size)[2]
    rec = scan_features(scan).y[s]
    net = MlpTexture(model).render(finger_from_scan(scan))[s]
    f, pr = welch_psd(rec, scan.fs_hz)
    _, pn = welch_psd(net, scan.fs_hz)
    _, pl = welch_psd(_synth(lpc, _third(scan, 2).speed_mm_s, 11), scan.fs_hz)
    paths = [str(plot_spectra(out / "mlp_thesis_felt.png", [
        ("felt 20 mm/s, a_z, test third: thesis network", f, pr, pn),
        ("felt 20 mm/s, a_z, test third: LPC family", f, pr, pl)],
        "recorded (blue) against model (orange)"))]
    return paths


IDENTIFY_SURFACES = ("R1", "R2", "canvas", "corduroy", "cork", "felt", "sandpaper_p80",
                     "wood_grain")


def identification() -> list[tuple[str, dict, float]]:
    """docs/texture_families.md's comparison (same surfaces, strokes and identifier:
    ``fydpad.texture.evaluation.identify``) for the networks: one 6 s training stroke at 20 mm/s per
    surface (seed 1), three test strokes each (seeds 101-103)."""
    from fydpad.texture.evaluation.identify import (
        by_surface,
        fit_per_surface,
        identify_families,
    )

    train = [generate_scan(n, 20.0, 6.0, seed=1, friction=True) for n in IDENTIFY_SURFACES]
    test = [generate_scan(n, 20.0, 6.0, seed=s, friction=True) for n in IDENTIFY_SURFACES
            for s in (101, 102, 103)]
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, opts in (("mlp", {"learning_rate": 0.3}),
                           ("mlp", {"mode": "batch", "init_range": 0.5})):
            models, labels = fit_per_surface(kind, by_surface(train), **opts)
            out.append((kind, opts, identify_families(models, labels, test).rate))
    return out


def main() -> None:
    import sys

    if len(sys.argv) == 3 and sys.argv[1] == "--plot":
        for p in plot_figures(sys.argv[2]):
            print(p)
        return
    if sys.argv[1:] == ["--identify"]:
        for kind, opts, rate in identification():
            print(f"{kind} {opts}: identification rate {rate:.3f} over "
                  f"{3 * len(IDENTIFY_SURFACES)} strokes")
        return
    print("thesis network (3-10-1) vs LPC (the paper's method), z acceleration, test thirds")
    print(f"{'texture':9s} {'force':9s} {'stop':>10s} {'ep':>4s} {'R2 mlp':>8s} {'R2 lpc':>8s} "
          f"{'R2 lin':>7s} {'corr mlp':>8s} {'corr lpc':>8s} {'LSD mlp':>8s} {'LSD lpc':>8s} "
          f"{'rms mlp':>8s}")
    variants = ((TrainConfig(), ""), (TrainConfig(mode="batch", init_range=0.5), "*"))
    for name in TEXTURES_EVAL:
        for force in ("generator", "profile"):
            for cfg, lab in variants:
                r = thesis_vs_lpc(name, cfg, force=force)
                if r["stop"] == "diverged":
                    print(f"{name + lab:9s} {force:9s} {'diverged':>10s} in the first epoch")
                    continue
                print(f"{name + lab:9s} {force:9s} {r['stop']:>10s} {r['epochs']:4d} "
                      f"{r['r2_mlp']:8.3f} {r['r2_lpc']:8.3f} {r['r2_linear_ceiling']:7.3f} "
                      f"{r['corr_mlp']:8.3f} {r['corr_lpc']:8.3f} {r['lsd_mlp']:8.2f} "
                      f"{r['lsd_lpc']:8.2f} {r['rms_ratio_mlp']:8.3f}")
    print("   * batch steepest descent, weights initialised in [-0.5, 0.5] (not the thesis')")


if __name__ == "__main__":
    main()
