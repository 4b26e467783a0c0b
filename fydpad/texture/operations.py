"""What ``fydpad texture`` runs, for every family through the family contract: fit,
synthesize, evaluate (a second recording as the ceiling), identify and compare. Each
returns its results and the lines to print; the command parses arguments and prints."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.channels import open_channel
from fydpad.errors import UserError
from fydpad.texture.evaluation.evaluate import (
    BIN_HZ,
    TARGET_LSD_OVER_CEILING_DB,
    TARGET_PSD_CORRELATION,
    Comparison,
    ceiling,
    evaluate_family,
    meets_targets,
    unfair_ceiling,
    verdict_on_means,
    welch_psd,
)
from fydpad.texture.evaluation.identify import (
    Identification,
    compare_families,
    identify_families,
)
from fydpad.texture.families import fitted_kind, get_kind, load_family, spec_kind
from fydpad.texture.families.friction import FrictionFamily, friction_coefficient
from fydpad.texture.family import (
    TextureFamily,
    constant_stroke,
    finger_from_scan,
    save_model_json,
)
from fydpad.texture.lpc.coverage import describe, inside
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.plots import plot_against_ceiling, plot_confusion, plot_spectra
from fydpad.texture.scan_io import Scan, read_scans
from vision.recording import CsvRowWriter

Array = NDArray[np.float64]
#: The lead-in rendered and dropped before a steady synthesis: filters and gates settled.
LEAD_IN_S = 0.5
#: The speed tolerance (mm/s) of a second recording's fairness check.
SECOND_TOLERANCE_MM_S = 5.0
TARGETS = (f"correlation >= {TARGET_PSD_CORRELATION:g}, LSD <= ceiling + "
           f"{TARGET_LSD_OVER_CEILING_DB:g} dB")


def caught_messages(caught: list) -> list[str]:
    """Python warnings as their messages, each once."""
    return list(dict.fromkeys(str(w.message) for w in caught))


@dataclass
class Fitted:
    data: dict[str, Any]
    lines: list[str]
    #: Warnings raised while fitting (about the scans named), and about the fit as a whole.
    warnings: list[str]
    notes: list[str]


def fit_model(kind: str, scan_paths: list[str], options: dict[str, Any], out: str,
              plot: str | None = None, extra: dict[str, Any] | None = None) -> Fitted:
    """Fit a ``kind`` model with the family's ``fit_options`` from ``options`` and
    ``extra`` (``--set KEY=VALUE``), and write it to ``out`` (strict JSON)."""
    k = fitted_kind(kind)
    if plot and k.plot is None:
        raise UserError(f"--plot {plot}: the {kind} fit draws no figure (the lpc fit does)")
    reported: list[str] = []
    given = {**options, "report": reported.extend}
    opts = {name: given[name] for name in k.fit_options if name in given}
    if extra:
        if not k.set_options:
            raise UserError(f"--set {', '.join(sorted(extra))}: the {kind} fit takes its "
                            "options as flags (fit --help)")
        opts.update(extra)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scans = read_scans(scan_paths)
        if scans and k.check_options is not None:
            k.check_options(opts, scans[0].fs_hz)
        notes = k.notes(scans, opts) if k.notes is not None else []
        try:
            data = k.fit(scans, **opts)
        except TypeError as exc:  # an option this family's fit does not take
            raise UserError(f"fit --kind {kind}: {exc}") from None
        lines = k.describe(data, out) if k.describe is not None else [f"{kind} model"]
        if plot:
            k.plot(plot, scans, data, opts)
    save_model_json(data, out)
    return Fitted(data, [f"{out}: {lines[0]}", *lines[1:], *reported],
                  caught_messages(caught), notes)


@dataclass
class Synthesis:
    family: TextureFamily
    channel: str
    rate_hz: float
    t_s: Array
    y: Array
    force_n: float | None
    #: The unscanned speed spans the synthesis speed lies in (the model interpolates).
    unscanned: list[tuple[float, float]]
    warnings: list[str]

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.y * self.y))) if self.y.size else 0.0


def synthesize(spec: str, *, speed_mm_s: float, seconds: float, channel: str | None = None,
               force_n: float | None = None, audio_hz: float = 48_000.0,
               x0_mm: float | None = None, kind: str | None = None,
               **parameters: Any) -> Synthesis:
    """A constant-speed stroke rendered by the model of ``spec`` on ``channel`` (default
    vibration) after a lead-in of ``LEAD_IN_S``, with the render ``parameters`` it has."""
    if not (math.isfinite(speed_mm_s) and speed_mm_s >= 0):
        raise UserError(f"--speed-mm-s {speed_mm_s:g}: must be a finite speed >= 0 (mm/s)")
    if not (math.isfinite(seconds) and seconds > 0):
        raise UserError("--seconds must be positive")
    found = spec_kind(spec)
    if kind is not None and kind != found:
        raise UserError(f"{spec}: key 'kind' is {found!r}, not --kind {kind}")
    family = load_family(spec)
    if "force_n" in family.needs and force_n is None:
        title = get_kind(family.kind).title or family.kind
        raise UserError(f"{spec}: a {title} model is indexed by speed and force: give "
                        "--force-n (N)")
    force = 1.0 if force_n is None else force_n
    if not (math.isfinite(force) and force >= 0):
        raise UserError("--force-n must be >= 0")
    channel = channel or "vibration"
    if channel not in family.channels:
        raise UserError(f"{spec}: a {family.kind} model renders "
                        f"{', '.join(family.channels)}, not --channel {channel}")
    rate = audio_hz if channel == "audio" else family.channels[channel]
    family.channels[channel] = rate
    for name, value in parameters.items():  # those it has (None: the model's own)
        if value is not None and name in family.parameters:
            family.set_parameter(name, value)
    x0 = family.x0_mm if x0_mm is None else x0_mm
    lead = constant_stroke(speed_mm_s, LEAD_IN_S, rate, x0 - speed_mm_s * LEAD_IN_S, force)
    finger = constant_stroke(speed_mm_s, seconds, rate, x0_mm=x0, force_n=force)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            family.render(lead, channel)
            y = family.render(finger, channel)
    except ValueError as exc:
        raise UserError(f"{spec}: {exc}") from None
    gaps = [g for g in family.unscanned_speeds() or [] if inside(speed_mm_s, [g])]
    return Synthesis(family, channel, rate, finger.t_s, y, force_n, gaps,
                     caught_messages(caught))


def write_synthesis(out: str, syn: Synthesis, speed_mm_s: float) -> None:
    """``.wav``: a WAV file (peak-normalised float); else CSV ``t_s,a`` (vibration,
    m/s^2) or ``t_s,<channel>``."""
    if out.lower().endswith(".wav"):
        with open_channel(f"wav:{out}", syn.rate_hz) as ch:
            ch.write(np.asarray(syn.y, float))
        return
    fam = syn.family
    col = "a" if syn.channel == "vibration" else syn.channel
    params = " ".join(f"{k}={v}" for k, v in fam.parameters.items() if v is not None)
    comment = (f"kind={fam.kind} surface={fam.surface} channel={syn.channel} "
               f"speed_mm_s={speed_mm_s:g}"
               + (f" force_n={syn.force_n:g}" if syn.force_n is not None else "")
               + (f" {params}" if params else ""))
    with CsvRowWriter(out, ("t_s", col), comment=comment, flush_every_s=math.inf) as wr:
        for t, v in zip(syn.t_s.tolist(), syn.y.tolist(), strict=True):
            wr.write(t, v)


@dataclass
class Evaluated:
    """One scan's evaluation: its JSON fields, the lines to print, what the plot needs."""

    out: dict
    c: Comparison
    f_hz: Array
    recorded: Array
    synthesized: Array
    label: str
    #: ``--second``: its Welch spectrum, and why it sets no fair ceiling (None: fair).
    second_psd: Array | None = None
    unfair: str | None = None
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def _second(path: str, scan: Any, scan_mask: NDArray[np.bool_], family: TextureFamily
            ) -> tuple[Array, str | None, dict]:
    """A ``--second`` recording's spectrum over the samples the family covers, why it
    sets no fair ceiling, and the facts that say so."""
    second = read_scans([path])[0]
    if abs(second.fs_hz - scan.fs_hz) > 1e-6 * scan.fs_hz:
        raise UserError(f"{path}: column 't_s': sample rate {second.fs_hz:g} Hz, the "
                        f"scan's {scan.fs_hz:g} Hz")
    mask = family.covers(second.speed_mm_s)
    try:
        _, p2 = welch_psd(preprocess(second.acc, second.fs_hz, family.highpass_hz),
                          second.fs_hz, mask)
    except ValueError:
        raise UserError(f"{path}: {int(mask.sum())} of its {mask.size} samples are "
                        f"within the model's speeds (column 'speed_mm_s'), in no run of the "
                        f"{round(second.fs_hz / BIN_HZ)} a {BIN_HZ:g} Hz-bin spectrum "
                        "needs") from None
    v1, v2 = scan.speed_mm_s[scan_mask], second.speed_mm_s[mask]
    unfair = unfair_ceiling(v1, v2, scan.fs_hz, SECOND_TOLERANCE_MM_S,
                            scan.meta.get("surface"), second.meta.get("surface"))
    facts = {"second_surface": second.surface, "second_seconds": v2.size / second.fs_hz,
             "second_median_speed_mm_s": float(np.median(v2)),
             "scan_seconds": v1.size / scan.fs_hz,
             "scan_median_speed_mm_s": float(np.median(v1))}
    return p2, unfair, facts


def evaluate_scan_file(spec: str, family: TextureFamily, path: str, second: str | None,
                       seed: int) -> Evaluated:
    """:func:`evaluate_family` on one scan file, with ``second`` the ceiling and the
    targets' verdict (none without a fair ceiling)."""
    scan = read_scans([path])[0]
    mask = family.covers(scan.speed_mm_s)
    if mask.sum() < scan.fs_hz / 2:
        raise UserError(f"{path}: column 'speed_mm_s': too little of the scan "
                        f"({int(mask.sum())} samples) is within the model's speeds")
    p2, unfair, facts = _second(second, scan, mask, family) if second else (None, None, {})
    c, f, pr, ps = evaluate_family(family, scan, seed=seed, mask=mask, name=spec)
    gaps = family.unscanned_speeds()
    share = None if gaps is None else float(np.mean(inside(scan.speed_mm_s[mask], gaps)))
    out = {"model": spec, "kind": family.kind, "scan": path, **asdict(c),
           "interpolated_share": share,
           "note": "time_correlation compares independent realisations: ~0 expected"}
    ev = Evaluated(out, c, f, pr, ps, f"{scan.surface} vs {family.surface or family.kind}",
                   p2, unfair)
    ev.lines.append(
        f"{family.kind}: power-spectrum correlation (20-500 Hz) {c.psd_correlation:.3f} "
        f"(dB spectra {c.psd_correlation_db:.3f}); log-spectral distance {c.lsd_db:.2f} dB; "
        f"time correlation {c.time_correlation:.3f} (independent realisations: ~0 expected)")
    if isinstance(family, FrictionFamily) and scan.friction_n is not None \
            and scan.force_n is not None:
        mu_rec = friction_coefficient(scan.friction_n, scan.force_n)
        mu_syn = family.mu_at(finger_from_scan(scan).x_mm)
        ok = np.isfinite(mu_rec) & (scan.speed_mm_s > 0.5 * np.median(scan.speed_mm_s))
        err = float(np.sqrt(np.mean((mu_rec[ok] - mu_syn[ok]) ** 2)) / np.mean(mu_syn[ok]))
        out["mu_rms_error_rel"] = err
        ev.lines.append(f"mu(x) RMS error {100 * err:.2f} % of the mean (unfiltered "
                        "recording)")
    if p2 is not None:
        ceil = ceiling(pr, p2, f)
        met = None if unfair else meets_targets(c, ceil)
        out.update(second=second, ceiling=asdict(ceil), **facts,
                   lsd_over_ceiling_db=c.lsd_db - ceil.lsd_db, targets_met=met,
                   **({"ceiling_note": f"no fair ceiling: {unfair}"} if unfair else {}))
        verdict = "no verdict" if met is None else "targets met" if met else "targets not met"
        ev.lines.append(
            f"ceiling ({second} against the scan): correlation {ceil.psd_correlation:.3f}, "
            f"LSD {ceil.lsd_db:.2f} dB; the model's LSD is {c.lsd_db - ceil.lsd_db:+.2f} dB "
            f"over it: {verdict} ({TARGETS})")
        if unfair:
            ev.warnings.append(f"{second} sets no fair ceiling: {unfair}")
    if share:
        ev.lines.append(f"{share:.1%} of the compared samples are at speeds no scan of the "
                        f"fit went at ({describe(gaps)}): the model interpolates there")
    return ev


def evaluate_model(spec: str, scan_paths: list[str], seconds: list[str] | None = None,
                   seed: int = 0) -> list[Evaluated]:
    """Each scan (the i-th its own noise draw, ``seed + i``) with its second recording."""
    if seconds and len(seconds) != len(scan_paths):
        raise UserError(f"--second: {len(seconds)} recording(s) for {len(scan_paths)} "
                        "scan(s): give --second once per scan, in the same order")
    family = load_family(spec)
    results = [evaluate_scan_file(spec, family, p, seconds[i] if seconds else None, seed + i)
               for i, p in enumerate(scan_paths)]
    for path, r in zip(scan_paths[1:], results[1:], strict=True):
        if r.f_hz.shape != results[0].f_hz.shape:  # their means need one frequency grid
            raise UserError(f"{path}: column 't_s': its sample rate differs from "
                            f"{scan_paths[0]}'s; several scans need one rate")
    return results


def fair(results: list[Evaluated]) -> list[Evaluated]:
    """The scans whose second recording sets a fair ceiling."""
    return [r for r in results if r.second_psd is not None and not r.unfair]


def over_scans(spec: str, results: list[Evaluated]) -> tuple[dict, list[str]]:
    """Several scans: the means of their figures and, where second recordings set fair
    ceilings, the targets on the means (one scan against one second recording is two
    random draws)."""
    mean: dict[str, Any] = {
        "psd_correlation": float(np.mean([r.c.psd_correlation for r in results])),
        "lsd_db": float(np.mean([r.c.lsd_db for r in results]))}
    lines = [f"mean over {len(results)} scans: power-spectrum correlation "
             f"{mean['psd_correlation']:.3f}, log-spectral distance {mean['lsd_db']:.2f} dB"]
    ok = fair(results)
    if any(r.second_psd is not None for r in results):
        mean.update(fair_pairs=len(ok), **dict.fromkeys((
            "fair_psd_correlation", "ceiling_lsd_db", "lsd_over_ceiling_db",
            "psd_correlation_se", "lsd_over_ceiling_se_db", "targets_met", "verdict_decided")))
        if not ok:
            lines.append("no scan has a fair ceiling: no verdict")
    if ok:
        v = verdict_on_means([r.c.psd_correlation for r in ok],
                             [r.out["lsd_over_ceiling_db"] for r in ok])
        ceil = float(np.mean([r.out["ceiling"]["lsd_db"] for r in ok]))
        mean.update(fair_psd_correlation=v.psd_correlation, ceiling_lsd_db=ceil,
                    lsd_over_ceiling_db=v.lsd_over_ceiling_db,
                    psd_correlation_se=v.psd_correlation_se,
                    lsd_over_ceiling_se_db=v.lsd_over_ceiling_se_db, targets_met=v.met,
                    verdict_decided=v.decided if len(ok) > 1 else None)
        se = ("" if v.lsd_over_ceiling_se_db is None else
              f" (standard error {v.lsd_over_ceiling_se_db:.2f})")
        cse = ("" if v.psd_correlation_se is None else
               f" (standard error {v.psd_correlation_se:.3f})")
        lines.append(
            f"on the means of the {len(ok)} scan(s) with a fair ceiling: correlation "
            f"{v.psd_correlation:.3f}{cse}, LSD {v.lsd_over_ceiling_db:+.2f} dB{se} over the "
            f"mean ceiling {ceil:.2f} dB: {'targets met' if v.met else 'targets not met'} "
            f"({TARGETS})")
        if len(ok) > 1 and not v.decided:
            lines.append("  within two standard errors of a limit: more strokes would decide it")
    return {"model": spec, "scans": [r.out for r in results], "mean": mean}, lines


def plot_evaluation(path: str, results: list[Evaluated]) -> None:
    """The spectra (with second recordings their differences; several scans: the means
    over those with a fair ceiling, else over all)."""
    many = len(results) > 1
    ok = fair(results) if many else [r for r in results if r.second_psd is not None]
    pool = ok or results  # with fair ceilings, the pairs the verdict is on
    rec = np.mean([x.recorded for x in pool], axis=0)
    syn = np.mean([x.synthesized for x in pool], axis=0)
    mean = "mean " if many else ""
    title = (f"{mean}corr {np.mean([x.c.psd_correlation for x in pool]):.3f}, {mean}"
             f"LSD {np.mean([x.c.lsd_db for x in pool]):.2f} dB")
    label = results[0].label + (f", mean of {len(pool)} scans" if many else "")
    if not ok:
        plot_spectra(path, [(label, results[0].f_hz, rec, syn)], title)
        return
    ceil = float(np.mean([x.out["ceiling"]["lsd_db"] for x in ok]))
    plot_against_ceiling(path, results[0].f_hz, rec, syn,
                         np.mean([x.second_psd for x in ok], axis=0),
                         f"{label}: {title} (ceiling {ceil:.2f} dB)")


def identify_models(specs: list[str], scan_paths: list[str], *, distance: str | None = None,
                    seed: int = 0, wrap: Callable[[Iterable], Iterable] = lambda it: it
                    ) -> tuple[str, Identification]:
    """Every scan assigned to the model of ``specs`` (one family, one per surface) of
    nearest spectrum along the scan's stroke (``distance``: the family's default)."""
    kinds = {spec_kind(p) for p in specs}
    if len(kinds) > 1:
        raise UserError(f"identify: the models mix kinds {', '.join(sorted(kinds))}; give "
                        "one family's models per run (one confusion matrix per family)")
    kind = next(iter(kinds))
    fams = [load_family(p) for p in specs]
    labels = [f.surface or Path(p).stem for f, p in zip(fams, specs, strict=True)]
    scans = read_scans(scan_paths)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = identify_families(fams, labels, scans, seed=seed, wrap=wrap,
                                  distance=distance or get_kind(kind).distance,
                                  model_names=specs)
    return kind, ident


def compare_command(train: list[Scan], test: list[Scan], kinds: list[str], out_dir: Path,
                    seed: int = 0) -> tuple[dict, list[str], dict[str, dict]]:
    """Per family the confusion matrix (plots in ``out_dir``), and the fitted models
    (kind -> surface -> model)."""
    unknown = [k for k in kinds if get_kind(k).fit is None]
    if unknown:
        raise UserError(f"--kinds: unknown {', '.join(unknown)}")
    result: dict = {"train": [s.path for s in train], "scans": [s.path for s in test],
                    "families": {}}
    lines, fitted = [], {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, got in compare_families(train, test, kinds, seed=seed).items():
            if isinstance(got, str):
                lines.append(f"{kind:9s} {got}")
                result["families"][kind] = {"error": got}
                continue
            ident, fitted[kind] = got
            lines.append(f"{kind:9s} identification rate {ident.rate:.1%} ({len(test)} scans)")
            result["families"][kind] = ident.to_json()
            plot_confusion(str(out_dir / f"confusion_{kind}.png"), ident,
                           f"{kind}: rate {ident.rate:.0%}")
    return result, lines, fitted
