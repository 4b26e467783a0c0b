"""Choosing the LPC model form on the user's own scans by held-out validation
(docs/texture.md, "How fit chooses"): time blocks of each plateau and whole inner plateaus
held out in turn, each candidate fitted on the rest and scored by the log-spectral
distance of its synthesis along the held-out speeds; the simplest candidate within the
noise of the best is refitted on all the scans."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fydpad.texture.evaluation.evaluate import compare
from fydpad.texture.family import runs
from fydpad.texture.lpc.analysis import DEFAULT_SPEEDS_MM_S, DEFAULT_TOLERANCE_MM_S
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_paper, fit_texture
from fydpad.texture.lpc.model_file import TextureModel
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.scan_io import Scan

#: Simplest first: a tie within the noise goes to the earlier one.
CANDIDATES = ("paper", "calibrated")
BLOCKS = 2
MIN_PLATEAU_S = 4.5  # shorter: blocks under 2.25 s, too few 4 Hz Welch segments
#: The scoring renderer's table step (the station's is 0.25): each fold's table built at
#: half the cost, every speed within 0.25 mm/s of an entry.
SCORE_STEP_MM_S = 0.5
MIN_PIECE_S = 1.0  # training pieces shorter than this are dropped (too short for DFT321)


@dataclass
class CandidateScore:
    name: str
    block_lsd_db: list[float]  # time blocks, fold by fold, plateau by plateau
    between_lsd_db: list[float]  # inner plateaus held out whole

    @property
    def scores(self) -> NDArray[np.float64]:
        return np.asarray(self.block_lsd_db + self.between_lsd_db)

    @property
    def weights(self) -> NDArray[np.float64]:
        """The time blocks and the between-plateau blocks weigh half each."""
        nb, nt = len(self.block_lsd_db), len(self.between_lsd_db)
        if nb == 0 or nt == 0:
            return np.full(nb + nt, 1.0 / (nb + nt))
        return np.r_[np.full(nb, 0.5 / nb), np.full(nt, 0.5 / nt)]

    @property
    def mean_lsd_db(self) -> float:
        return float(self.weights @ self.scores)

    @property
    def spread_db(self) -> float:
        return float(np.std(self.scores, ddof=1)) if self.scores.size > 1 else 0.0

    def noise_to(self, best: CandidateScore) -> float:
        """The standard error of the weighted mean of the paired differences to ``best``."""
        d = self.scores - best.scores
        return float(np.sqrt(np.sum(self.weights ** 2) * np.var(d, ddof=1))) if d.size > 1 else 0.0


@dataclass
class Selection:
    winner: str
    validated: bool
    reason: str
    candidates: list[CandidateScore] = field(default_factory=list)
    noise_db: dict[str, float] = field(default_factory=dict)  # paired s.e. against the best
    plateaus_mm_s: list[float] = field(default_factory=list)

    def to_json(self) -> dict:
        r3 = lambda x: round(float(x), 3)  # noqa: E731
        return {
            "winner": self.winner, "validated": self.validated, "reason": self.reason,
            "score": "mean log-spectral distance (dB, 20-500 Hz, 4 Hz bins) on held-out blocks",
            "plateaus_mm_s": [r3(v) for v in self.plateaus_mm_s],
            "candidates": [
                {"name": c.name, "mean_lsd_db": r3(c.mean_lsd_db), "spread_db": r3(c.spread_db),
                 "time_block_lsd_db": [r3(x) for x in c.block_lsd_db],
                 "between_plateaus_lsd_db": [r3(x) for x in c.between_lsd_db],
                 "noise_to_best_db": r3(self.noise_db.get(c.name, 0.0))}
                for c in self.candidates],
        }


def fit_candidate(name: str, scans: Sequence[Scan], speeds_mm_s: Sequence[float], *,
                  min_seconds: float = 0.25,
                  wrap_iterations: Callable[[Iterable], Iterable] = lambda it: it,
                  **options: Any) -> TextureModel:
    """One candidate form fitted on ``scans``; ``options`` (order, tolerance_mm_s,
    highpass_hz, surface, drive_band_hz) go to either form, the rest to the calibrated."""
    if name == "paper":
        return fit_paper(scans, **options)
    if name != "calibrated":
        raise ValueError(f"unknown candidate {name!r}; one of {CANDIDATES}")
    return fit_texture(scans, speeds_mm_s=speeds_mm_s, min_seconds=min_seconds,
                       wrap_iterations=wrap_iterations, **options)


def plateaus(scans: Sequence[Scan], speeds_mm_s: Sequence[float], tolerance_mm_s: float
             ) -> list[tuple[float, int, int, int]]:
    """(target speed, scan index, start, stop) of each target's longest run within the
    tolerance, for the targets that have one of at least ``MIN_PLATEAU_S``."""
    out = []
    for s in sorted(float(v) for v in speeds_mm_s):
        # A hand sways about 10 % around a plateau: widened to 20 % of its speed.
        found = [(i, a, b) for i, sc in enumerate(scans)
                 for a, b in runs(np.abs(sc.speed_mm_s - s) <= max(tolerance_mm_s, 0.2 * s),
                                  round(MIN_PLATEAU_S * sc.fs_hz))]
        if found:
            out.append((s, *max(found, key=lambda r: r[2] - r[1])))  # the first longest
    return out


def _piece(scan: Scan, a: int, b: int, tag: str) -> Scan:
    return replace(scan, path=f"{scan.path}[{tag}]", t_s=scan.t_s[a:b], acc=scan.acc[a:b],
                   speed_mm_s=scan.speed_mm_s[a:b],
                   force_n=None if scan.force_n is None else scan.force_n[a:b])


def _without(scans: Sequence[Scan], drop: list[NDArray[np.bool_]]) -> list[Scan]:
    """The scans cut into the pieces outside ``drop`` (one mask per scan)."""
    return [_piece(sc, a, b, f"{a}:{b}") for sc, d in zip(scans, drop, strict=True)
            for a, b in runs(~d, round(MIN_PIECE_S * sc.fs_hz))]


def held_out_lsd_db(model: TextureModel, blocks: Sequence[Scan]) -> list[float]:
    """Each block's LSD: the model synthesized along the block's speed trace (one
    renderer, reseeded to 0 per block) against the block's DFT321 signal."""
    r = TextureRenderer(model, ramp_s=1e-6, step_mm_s=SCORE_STEP_MM_S)
    out = []
    for blk in blocks:
        r.reset()
        r.reseed(0)
        r.warmup(float(blk.speed_mm_s[0]), 0.5)
        syn = r.block(blk.speed_mm_s, True)
        c, *_ = compare(preprocess(blk.acc, blk.fs_hz, model.highpass_hz), syn, blk.fs_hz)
        out.append(c.lsd_db)
    return out


def select_model(
    scans: Sequence[Scan], *, speeds_mm_s: Sequence[float] = DEFAULT_SPEEDS_MM_S,
    tolerance_mm_s: float = DEFAULT_TOLERANCE_MM_S,
    wrap: Callable[[Iterable], Iterable] = lambda it: it, **fit_options: Any,
) -> tuple[TextureModel, Selection]:
    """The validated winner refitted on all ``scans`` and the validation (module doc).
    ``fit_options`` go to :func:`fit_candidate`; ``wrap`` wraps the list of (fold,
    candidate) fits (a progress bar)."""
    scans = list(scans)
    kw = {"tolerance_mm_s": tolerance_mm_s, **fit_options}
    found = plateaus(scans, speeds_mm_s, tolerance_mm_s)
    targets = [s for s, *_ in found]
    if len(found) < 2:
        reason = (f"{len(found)} speed plateau(s) of at least {MIN_PLATEAU_S:g} s within "
                  f"{tolerance_mm_s:g} mm/s of {', '.join(f'{v:g}' for v in speeds_mm_s)} "
                  "mm/s: cannot validate, the plain paper method is fitted")
        model = fit_candidate("paper", scans, speeds_mm_s, **kw)
        sel = Selection("paper", False, reason)
        model.selection = sel.to_json()
        return model, sel
    folds = []  # (kind, training scans, speeds to fit, held-out blocks)
    for k in range(BLOCKS):
        drop = [np.zeros(sc.speed_mm_s.size, bool) for sc in scans]
        held = []
        for _, i, a, b in found:
            lo, hi = a + (b - a) * k // BLOCKS, a + (b - a) * (k + 1) // BLOCKS
            drop[i][lo:hi] = True
            held.append(_piece(scans[i], lo, hi, f"block{k}"))
        folds.append(("block", _without(scans, drop), targets, held))
    for s, i, a, b in found[1:-1]:
        drop = [np.abs(sc.speed_mm_s - s) <= tolerance_mm_s for sc in scans]
        folds.append(("between", _without(scans, drop), [v for v in targets if v != s],
                      [_piece(scans[i], a, b, f"{s:g}")]))
    scores = {c: CandidateScore(c, [], []) for c in CANDIDATES}
    for (kind, train, speeds, held), c in wrap([(f, c) for f in folds for c in CANDIDATES]):
        # speeds a fold lacks, blocks beyond its speeds (clamped): the final fit says
        with warnings.catch_warnings(action="ignore"):
            got = held_out_lsd_db(fit_candidate(c, train, speeds, **kw), held)
        (scores[c].block_lsd_db if kind == "block" else scores[c].between_lsd_db).extend(got)
    table = list(scores.values())
    best = min(table, key=lambda t: t.mean_lsd_db)
    noise = {t.name: t.noise_to(best) for t in table}
    winner = next(t for t in table if t.mean_lsd_db - best.mean_lsd_db <= noise[t.name])
    reason = (f"lowest held-out LSD within the noise, simplest first "
              f"({len(folds)} folds, {best.scores.size} held-out blocks)")
    model = fit_candidate(winner.name, scans, targets, **kw)
    sel = Selection(winner.name, True, reason, table, noise, targets)
    model.selection = sel.to_json()
    return model, sel


def selection_table(sel: Selection) -> list[str]:
    """The validation as printed by ``fydpad texture fit``."""
    if not sel.validated:
        return [f"  validation: {sel.reason}"]
    lines = [f"  validation on plateaus {', '.join(f'{v:g}' for v in sel.plateaus_mm_s)} "
             "mm/s: mean held-out LSD (dB)",
             f"  {'candidate':<12}{'time blocks':>12}{'between':>9}{'mean':>7}{'spread':>8}"
             f"{'vs best +- noise':>18}"]
    best = min(c.mean_lsd_db for c in sel.candidates)
    for c in sel.candidates:
        between = f"{np.mean(c.between_lsd_db):9.2f}" if c.between_lsd_db else f"{'-':>9}"
        mark = "  <- chosen" if c.name == sel.winner else ""
        lines.append(f"  {c.name:<12}{np.mean(c.block_lsd_db):12.2f}{between}"
                     f"{c.mean_lsd_db:7.2f}{c.spread_db:8.2f}"
                     f"{c.mean_lsd_db - best:+10.2f} +- {sel.noise_db[c.name]:.2f}{mark}")
    return lines
