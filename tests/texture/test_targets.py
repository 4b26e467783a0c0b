"""Issue 7's targets on the generator's held-out strokes (strokes the fit never saw).

Targets: power-spectrum correlation >= 0.95 (Welch 4 Hz bins, 20-500 Hz) and a
log-spectral distance within 0.25 dB of what a second recording of the same surface
scores against the same held-out stroke (the ceiling), at a modelled speed (20 mm/s)
and between modelled speeds (25 mm/s); identification 100 % over every texture.

The thresholds are the issue's and are not loosened. Where the code does not meet a
target yet, the test is marked ``xfail(strict=True)`` with the measured figures: it
fails loudly the day the target is met, so the mark cannot outlive the gap. Data are
kept small (4 textures, one 8 s training stroke per speed) to stay within the suite's
time budget; the full figures are in docs/texture.md.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import compare, evaluate_scan, evaluation_mask
from fydpad.texture.fit import fit_texture
from fydpad.texture.identify import identify
from fydpad.texture.scan_generator import TEXTURES, generate_scan

TARGET_TEXTURES = ("R1", "R2", "felt", "glass")
SPEEDS = (10.0, 20.0, 30.0, 40.0)


@pytest.fixture(scope="module")
def figures():
    """{(texture, speed, method): (corr, lsd, ceiling)} on held-out strokes."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in TARGET_TEXTURES:
            model, _ = fit_texture([generate_scan(name, s, 8.0, seed=1) for s in SPEEDS])
            for v in (20.0, 25.0):
                held = generate_scan(name, v, 8.0, seed=100)
                second = generate_scan(name, v, 8.0, seed=200)
                mask = evaluation_mask(held, model)
                ceil, *_ = compare(preprocess(held.acc, 1000.0), preprocess(second.acc, 1000.0),
                                   1000.0, mask & evaluation_mask(second, model))
                for method in ("lsf", "linear"):
                    c, _ = evaluate_scan(model, held, method=method, mask=mask)
                    out[(name, v, method)] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
    return out


def _check(figures, speed: float, method: str) -> None:
    for name in TARGET_TEXTURES:
        corr, lsd, ceil = figures[(name, speed, method)]
        assert corr >= 0.95, f"{name} at {speed:g} mm/s: correlation {corr:.3f}"
        assert lsd <= ceil + 0.25, f"{name} at {speed:g} mm/s: LSD {lsd:.2f} dB, ceiling {ceil:.2f}"


@pytest.mark.xfail(strict=True, reason="measured at 20 mm/s: R1 corr 0.946 (< 0.95); LSD above "
                   "the ceiling by 0.26 dB (R2, felt; > 0.25), R1 +0.15, glass +0.20 "
                   "(docs/texture.md)")
def test_targets_at_a_modelled_speed(figures):
    _check(figures, 20.0, "lsf")


@pytest.mark.xfail(strict=True, reason="measured at 25 mm/s: LSD 1.7-2.4 dB above the ceiling "
                   "for R1, R2, felt (glass meets it): a spatial texture's spectrum stretches "
                   "with speed, LSF interpolation does not stretch it (docs/texture.md)")
def test_targets_between_modelled_speeds(figures):
    _check(figures, 25.0, "lsf")


def test_stable_interpolation_is_no_worse_than_the_papers_linear(figures):
    """Mean LSD over textures and speeds: the LSF way against the paper's plain way."""
    mine = np.mean([v[1] for k, v in figures.items() if k[2] == "lsf"])
    paper = np.mean([v[1] for k, v in figures.items() if k[2] == "linear"])
    assert mine <= paper + 0.05, (mine, paper)


def test_a_model_is_closer_to_its_own_surface_than_the_ceiling_is_far(figures):
    """Sanity of the ceiling: two recordings of one surface agree to within a few dB."""
    assert all(v[2] < 3.0 for v in figures.values())


@pytest.fixture(scope="module")
def identification():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = [fit_texture([generate_scan(n, s, 5.0, seed=1) for s in SPEEDS])[0]
                  for n in TEXTURES]
        scans = [generate_scan(n, v, 4.0, seed=50) for n in TEXTURES for v in (15.0, 30.0)]
        return identify(models, scans)


def test_identification_is_well_above_chance(identification):
    assert len(identification.labels) >= 12
    assert identification.rate >= 0.75  # a regression guard, not the target (below)


@pytest.mark.xfail(strict=True, reason="measured: 24 of 28 scans (86 %, 14 textures at 15 and "
                   "30 mm/s; the 4 misses at 15 mm/s) (docs/texture.md)")
def test_identification_target_100_percent(identification):
    assert identification.rate == 1.0
