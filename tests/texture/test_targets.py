"""Issue 7's targets on the generator's held-out strokes (strokes the fit never saw).

Targets: power-spectrum correlation >= 0.95 (Welch 4 Hz bins, 20-500 Hz) and a
log-spectral distance within 0.25 dB of what a second recording of the same surface
scores against the same held-out stroke (the ceiling), at a modelled speed (20 mm/s)
and between modelled speeds (25 mm/s); identification 100 % over every texture. On the
4-texture set the default fit (R1 and R2's lines, the calibrated spectrum for felt and
glass) meets both; the per-speed forms on the whole signal (``lines="off"``: the pooled
fit with the default interpolation ("stretch"), LSF and the paper's linear way, and the
options) are checked beside it; the calibrated form alone is in test_free_form.py; the
14-texture target and identification use the default fit.

The thresholds are the issue's and are not loosened. Where the code does not meet a
target yet, the test is marked ``xfail(strict=True)`` with the measured figures: it
fails loudly the day the target is met, so the mark cannot outlive the gap. Data are
kept small (4 textures, one 8 s training stroke per speed) to stay within the suite's
time budget; the 14-texture target at a modelled speed uses 12 s held-out strokes and
two 10 s training strokes per speed (the ceiling is out of reach on shorter strokes:
docs/texture.md, "Held-out protocol"); the full figures are in docs/texture.md.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from fydpad.texture.dft321 import preprocess
from fydpad.texture.evaluate import (
    compare,
    compare_recordings,
    evaluate_scan,
    evaluation_mask,
    verdict_on_means,
)
from fydpad.texture.fit import fit_texture
from fydpad.texture.identify import identify
from fydpad.texture.scan_generator import TEXTURES, generate_scan
from tests.texture.heldout import held_out

TARGET_TEXTURES = ("R1", "R2", "felt", "glass")
SPEEDS = (10.0, 20.0, 30.0, 40.0)
HELD_SPEEDS = (15.0, 30.0)
NORMALISED_GRID = (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0)


@pytest.fixture(scope="module")
def figures():
    """{(texture, speed, method): (corr, lsd, ceiling)} on held-out strokes."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in TARGET_TEXTURES:
            train = [generate_scan(name, s, 8.0, seed=1) for s in SPEEDS]
            # The per-speed forms on the whole signal (lines off: with them, R1 and R2's
            # forms would model only what their lines leave; the lines: test_lines.py and
            # the default fit below).
            model, _ = fit_texture(train, free_form=None, lines="off")  # the pooled fit
            # The option: every 5 mm/s, each speed fitted on runs moved to it in space.
            norm, _ = fit_texture(train, speeds_mm_s=NORMALISED_GRID, speed_normalise=True,
                                  lines="off")
            # The two-part model: fixed tool part, surface part moving with speed.
            two, _ = fit_texture(train, two_part=True, lines="off")
            for v in (20.0, 25.0):
                held, mask, ceil = held_out(name, v, model)
                for method in ("stretch", "lsf", "linear"):
                    c, _ = evaluate_scan(model, held, method=method, mask=mask)
                    out[(name, v, method)] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
                c, _ = evaluate_scan(norm, held, method="stretch", mask=mask)
                out[(name, v, "normalised")] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
                c, _ = evaluate_scan(two, held, method="stretch", mask=mask)
                out[(name, v, "two_part")] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
    return out


@pytest.fixture(scope="module")
def default_figures():
    """The default fit (fit_texture() as `fydpad texture fit` runs it: R1 and R2 get their
    lines, felt and glass the calibrated spectrum) on the ``figures`` protocol:
    {(texture, speed, "default"): (corr, lsd, ceiling)}."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in TARGET_TEXTURES:
            model, _ = fit_texture([generate_scan(name, s, 8.0, seed=1) for s in SPEEDS])
            assert (model.lines is not None) == (name in ("R1", "R2")), name
            for v in (20.0, 25.0):
                held, mask, ceil = held_out(name, v, model)
                c, _ = evaluate_scan(model, held, method="stretch", mask=mask)
                out[(name, v, "default")] = (c.psd_correlation, c.lsd_db, ceil.lsd_db)
    return out


def test_default_fit_meets_the_targets_at_a_modelled_speed(default_figures):
    """20 mm/s with the default fit: R1 and R2 by their lines, felt and glass by the
    calibrated form. Measured corr / LSD above the ceiling: R1 1.000 / +0.06, R2 0.995 /
    +0.06, felt 0.985 / -0.45, glass 0.983 / +0.09. Until session 14's hand (a speed
    drift of 6 % RMS that was 0.7-2.6 % mid-stroke) glass missed by 0.03 dB (+0.28), a strict
    xfail (docs/texture.md)."""
    _check(default_figures, 20.0, "default")


def test_default_fit_meets_the_targets_between_modelled_speeds(default_figures):
    """25 mm/s, between the fitted speeds (measured): R1 0.999 / -0.65, R2 0.999 / -0.28,
    felt 0.986 / -0.35, glass 0.975 / +0.08 (before session 14's hand +0.21, +0.18, +0.17,
    +0.12). Before the lines R1 and R2 missed it by 0.16-0.30 dB with every form."""
    _check(default_figures, 25.0, "default")


def _check(figures, speed: float, method: str) -> None:
    for name in TARGET_TEXTURES:
        corr, lsd, ceil = figures[(name, speed, method)]
        assert corr >= 0.95, f"{name} at {speed:g} mm/s: correlation {corr:.3f}"
        assert lsd <= ceil + 0.25, f"{name} at {speed:g} mm/s: LSD {lsd:.2f} dB, ceiling {ceil:.2f}"


@pytest.mark.xfail(strict=True, reason="measured at 20 mm/s, pooled fit, 'stretch' (corr / LSD "
                   "over the ceiling): R1 0.967 / +0.29, R2 0.985 / +0.44 miss, felt 0.985 / "
                   "-0.21, glass 0.980 / +0.11 meet. Each speed pools its runs over +-5 mm/s, "
                   "and since session 14 the hand's speed wanders 9 % RMS (its drift was "
                   "0.7-2.6 % mid-stroke before, 6 % meant): as we read it, a grating's "
                   "comb smears over the pooled speeds. Met before (R1 -0.14, R2 +0.12); "
                   "the default fit (the "
                   "lines) and the two-part model meet it (docs/texture.md)")
def test_targets_at_a_modelled_speed(figures):
    """The pooled fit with "stretch" on the whole signal (lines off)."""
    _check(figures, 20.0, "stretch")


@pytest.mark.xfail(strict=True, reason="measured at 25 mm/s, pooled fit, 'stretch': LSD above the "
                   "ceiling by 0.39 (R1), 0.90 (R2), 0.44 dB (felt), glass +0.22 meets it; corr "
                   "0.864 (R1), 0.933 (R2) (LSF: +0.79, +1.20, +0.42 dB, corr 0.759, 0.906; "
                   "before session 14's hand +1.50, +1.50, +1.02): the spectrum between fitted "
                   "speeds is not a stretch of its neighbours' (docs/texture.md)")
def test_targets_between_modelled_speeds(figures):
    _check(figures, 25.0, "stretch")


def test_speed_normalised_fit_closes_most_of_the_gap_between_speeds(figures):
    """fit_texture(speed_normalise=True) on the same strokes, every 5 mm/s: mean LSD above
    the ceiling at 25 mm/s falls below half the pooled fit's (measured: R1 -0.40, R2
    +0.26, felt -0.42, glass +0.18 dB against +0.39, +0.90, +0.44, +0.22)."""
    gap = {m: np.mean([figures[(n, 25.0, m)][1] - figures[(n, 25.0, m)][2]
                       for n in TARGET_TEXTURES]) for m in ("stretch", "normalised")}
    assert gap["normalised"] < 0.5 * gap["stretch"], gap


@pytest.mark.xfail(strict=True, reason="measured with fit_texture(speed_normalise=True), "
                   "speeds every 5 mm/s: at 25 mm/s R2's LSD is 0.26 dB above the ceiling "
                   "(R1 -0.40, felt -0.42, glass +0.18; corr 0.952-0.986); at 20 mm/s R2 "
                   "+0.32 (R1 +0.20; session 14; before its hand R1 +0.55, R2 +0.80 at 25 mm/s) "
                   "(docs/texture.md)")
def test_targets_between_modelled_speeds_speed_normalised(figures):
    _check(figures, 25.0, "normalised")


def test_two_part_model_meets_the_correlation_target_between_speeds(figures):
    """fit_texture(two_part=True): PSD correlation >= 0.95 at 25 mm/s on all four
    (measured 0.975-0.986; the pooled fit: R1 0.864, R2 0.933)."""
    for name in TARGET_TEXTURES:
        corr = figures[(name, 25.0, "two_part")][0]
        assert corr >= 0.95, f"{name}: correlation {corr:.3f}"


def test_two_part_model_closes_two_thirds_of_the_gap_between_speeds(figures):
    """Mean LSD above the ceiling at 25 mm/s: measured -0.17 dB (R1 -0.44, R2 +0.06, felt
    -0.36, glass +0.06) against the pooled fit's +0.49. Before session 14's hand, whose
    strokes wander 9 % RMS, +0.37 against +1.03: not two thirds."""
    gap = {m: np.mean([figures[(n, 25.0, m)][1] - figures[(n, 25.0, m)][2]
                       for n in TARGET_TEXTURES]) for m in ("stretch", "two_part")}
    assert gap["two_part"] < gap["stretch"] / 3, gap


def test_targets_between_modelled_speeds_two_part(figures):
    """fit_texture(two_part=True) at 25 mm/s: LSD above the ceiling R1 -0.44, R2 +0.06,
    felt -0.36, glass +0.06 dB, corr 0.975-0.986 (measured). Missed until session 14's
    hand, whose strokes wander 9 % RMS (R1 +0.54, R2 +0.60 in session 12)."""
    _check(figures, 25.0, "two_part")


def test_targets_at_a_modelled_speed_two_part(figures):
    """fit_texture(two_part=True) at 20 mm/s: R1 +0.16, R2 +0.20, felt -0.50, glass +0.11
    dB over the ceiling, corr >= 0.981 (measured; missed until session 14's hand: R2
    +0.33, glass +0.35)."""
    _check(figures, 20.0, "two_part")


@pytest.mark.parametrize("method", ["stretch", "lsf"])
def test_stable_interpolation_is_no_worse_than_the_papers_linear(figures, method):
    """Mean LSD over textures and speeds: ours against the paper's plain way."""
    mine = np.mean([v[1] for k, v in figures.items() if k[2] == method])
    paper = np.mean([v[1] for k, v in figures.items() if k[2] == "linear"])
    assert mine <= paper + 0.05, (mine, paper)


def test_stretch_is_closer_to_held_out_strokes_than_lsf(figures):
    """The default against the previous one: mean LSD over textures and both speeds."""
    mine = np.mean([v[1] for k, v in figures.items() if k[2] == "stretch"])
    lsf = np.mean([v[1] for k, v in figures.items() if k[2] == "lsf"])
    assert mine < lsf, (mine, lsf)


def test_a_model_is_closer_to_its_own_surface_than_the_ceiling_is_far(figures):
    """Sanity of the ceiling: two recordings of one surface agree to within a few dB."""
    assert all(v[2] < 3.0 for v in figures.values())


@pytest.fixture(scope="module")
def every_texture():
    """A model of every texture (one 5 s stroke per speed) and held-out 4 s strokes at
    15 and 30 mm/s: the identification set-up."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = [fit_texture([generate_scan(n, s, 5.0, seed=1) for s in SPEEDS])[0]
                  for n in TEXTURES]
        scans = [generate_scan(n, v, 4.0, seed=50) for n in TEXTURES for v in HELD_SPEEDS]
    return models, scans


# The protocol of the 14-texture target at a modelled speed (docs/texture.md, "Held-out
# protocol"): a second recording of the same surface clears the correlation target on
# 12 s strokes (0.980-0.997 at 30 mm/s, seeds 50/51) but not on 4 s ones (0.890-0.945 on
# five textures), so the held-out strokes are 12 s, as a real scan session's are; the
# models are fitted on two 10 s strokes per speed, as a lab would record. The
# thresholds are unchanged.
TRAIN_STROKES, TRAIN_S, HELD_S = 2, 10.0, 12.0


def _models(names, load_scale: float = 1.0) -> list:
    """The default fit of each texture on TRAIN_STROKES strokes of TRAIN_S per speed
    (seeds 1, 2, ...)."""
    return [fit_texture([generate_scan(n, s, TRAIN_S, seed=1 + j, load_scale=load_scale)
                         for s in SPEEDS for j in range(TRAIN_STROKES)])[0] for n in names]


@pytest.fixture(scope="module")
def every_texture_long():
    """A model of every texture (two 10 s strokes per speed, seeds 1-2) and its held-out
    12 s stroke at 30 mm/s (seed 50)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = _models(TEXTURES)
        scans = [generate_scan(n, 30.0, HELD_S, seed=50) for n in TEXTURES]
    return models, scans


def test_the_protocols_ceiling_clears_the_correlation_target():
    """Why 12 s held-out strokes: a second recording of the same surface (seed 51) scored
    against the held-out stroke (seed 50) at 30 mm/s reaches the 0.95 correlation on 12 s
    strokes for 12 of 14 textures (measured 0.979-0.996) but not on 4 s ones (R2 0.897,
    sandpaper_p80 0.896, cork 0.942, mesh_steel 0.302, aluminum_knurl 0.752): on 4 s the
    spectrum has too few Welch averages for the target to be reachable. The two combs
    whose harmonics cross a sharp tool mode, mesh_steel and aluminum_knurl, stay at 0.83
    on 12 s: their strong lines rise and fall as the hand wanders (9 % RMS since session
    14; 0.980-0.997 for all 14 before), and no two strokes wander alike. Their models meet
    the target (0.96-1.00 on the means of 4 and 8 strokes: the model is the average)."""
    ref = SimpleNamespace(speeds_mm_s=np.asarray(SPEEDS), tolerance_mm_s=5.0)
    corr = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seconds in (4.0, HELD_S):
            for n in TEXTURES:
                held = generate_scan(n, 30.0, seconds, seed=50)
                second = generate_scan(n, 30.0, seconds, seed=51)
                mask = evaluation_mask(held, ref) & evaluation_mask(second, ref)
                c, *_ = compare(preprocess(held.acc, 1000.0), preprocess(second.acc, 1000.0),
                                1000.0, mask)
                corr[(n, seconds)] = c.psd_correlation
    below = {s: {n for n in TEXTURES if corr[(n, s)] < 0.95} for s in (4.0, HELD_S)}
    assert below[HELD_S] <= {"mesh_steel", "aluminum_knurl"}, corr
    assert below[HELD_S] < below[4.0] and len(below[4.0]) >= 3, corr


def _misses(models, scans, speed: float) -> list[str]:
    """Textures that miss the targets on their held-out stroke at ``speed``; the ceiling
    is a second recording (seed 51) as long as the held-out stroke."""
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for model, held in zip(models, scans, strict=True):
            second = generate_scan(model.surface, speed, held.t_s.size / held.fs_hz, seed=51)
            mask = evaluation_mask(held, model)
            ceil = compare_recordings(held, second, model, mask)
            c, _ = evaluate_scan(model, held, method="stretch", mask=mask)
            if c.psd_correlation < 0.95 or c.lsd_db > ceil.lsd_db + 0.25:
                out.append(f"{model.surface} corr {c.psd_correlation:.3f} LSD {c.lsd_db:.2f} "
                           f"ceiling {ceil.lsd_db:.2f}")
    return out


def test_targets_at_a_modelled_speed_over_every_texture(every_texture_long):
    """30 mm/s with the default fit (the periodic surfaces' lines, the calibrated
    spectrum for the others; 12 s held-out strokes, two 10 s training strokes per speed):
    all 14 meet both (measured). Until session 14's hand 13 of 14: cork 0.003 dB past the
    limit, a strict xfail (docs/texture.md)."""
    misses = _misses(*every_texture_long, 30.0)
    assert not misses, misses


def _mean_figures(models, speed: float, strokes: int = 4, load_scale: float = 1.0
                  ) -> dict[str, tuple]:
    """{texture: (mean LSD - ceiling, its standard error, mean correlation, its standard
    error)} over ``strokes`` held-out 12 s strokes (seeds 1100 + j), each with its own
    second recording (seeds 2100 + j) and its own draw of the synthesis (4100 + j):
    benchmarks/texture_targets.py with train seed 1. One stroke and one second
    recording make the target a comparison of two draws, which a third recording of the
    surface fails in about one cell in five (docs/texture.md, "The targets on several
    strokes per cell"). ``load_scale``: the hand's load over the textures' own, as in
    ``generate_scan``."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for model in models:
            gap, corr = [], []
            for j in range(strokes):
                held = generate_scan(model.surface, speed, HELD_S, seed=1100 + j,
                                     load_scale=load_scale)
                second = generate_scan(model.surface, speed, HELD_S, seed=2100 + j,
                                       load_scale=load_scale)
                mask = evaluation_mask(held, model)
                ceil = compare_recordings(held, second, model, mask)
                c, _ = evaluate_scan(model, held, mask=mask, seed=4100 + j)
                gap.append(c.lsd_db - ceil.lsd_db)
                corr.append(c.psd_correlation)
            v = verdict_on_means(corr, gap)
            out[model.surface] = (v.lsd_over_ceiling_db, v.lsd_over_ceiling_se_db,
                                  v.psd_correlation, v.psd_correlation_se)
    return out


@pytest.fixture(scope="module")
def four_stroke_figures(every_texture_long):
    return {v: _mean_figures(every_texture_long[0], v) for v in (15.0, 30.0, 35.0)}


#: Textures whose strokes scatter too much for four of them to decide the target: the
#: means' verdict is the draw's (sandpaper_p80, a band edge crossing its tool mode: its
#: gap's standard error over four strokes is 0.1-1.4 dB; +0.68 at 30 mm/s with these
#: draws in session 11, -2.93 (SE 1.44) at 30 and +0.26 (SE 0.09) at 35 since session
#: 14). Checked to meet the target or stay undecided, so the exclusion covers no
#: decided miss.
UNDECIDED = ("sandpaper_p80",)


def _mean_misses(figures: dict[str, tuple], leave_out: tuple[str, ...] = ()) -> list[str]:
    return [f"{n} corr {corr:.3f} LSD - ceiling {gap:+.2f} (SE {se:.2f}) dB"
            for n, (gap, se, corr, _) in figures.items()
            if n not in leave_out and (corr < 0.95 or gap > 0.25)]


@pytest.mark.parametrize("speed", [30.0, 35.0])
def test_targets_on_four_strokes_per_texture_at_and_between_modelled_speeds(
        four_stroke_figures, speed):
    """On the means of four held-out strokes every texture meets both targets at 30 mm/s
    (a modelled speed) and at 35 mm/s (between modelled speeds), but sandpaper_p80, which
    four strokes cannot decide (UNDECIDED). Measured LSD over the ceiling -3.83 to +0.03
    dB, correlation 0.961-1.000 (session 14; -4.96 to +0.12, 0.978-1.000 before its
    hand)."""
    figures = four_stroke_figures[speed]
    misses = _mean_misses(figures, UNDECIDED)
    assert not misses, misses
    for n in UNDECIDED:
        gap, se, corr, se_corr = figures[n]
        met = gap <= 0.25 and corr >= 0.95
        assert met or abs(gap - 0.25) < 2 * se or abs(corr - 0.95) < 2 * se_corr, \
            (n, figures[n])


def test_four_strokes_in_the_middle_of_a_gap_miss_no_more_than_measured(four_stroke_figures):
    """15 mm/s, the middle of the gap between the 10 and 20 mm/s training strokes: the
    textures that miss on the means of four strokes are among those measured to or
    within 0.01 dB of it (a regression guard: the strict xfail below holds the target
    itself). Before session 14's hand six missed (R1, R2, sandpaper_p80, sandpaper_p320,
    glass, corduroy); with the base at 150 iterations (sessions 6-11) seven."""
    misses = {m.split()[0] for m in _mean_misses(four_stroke_figures[15.0])}
    assert misses <= {"R1", "glass"}, misses


@pytest.mark.xfail(strict=True, reason="measured at 15 mm/s, the middle of the gap between "
                   "the 10 and 20 mm/s training strokes, on the means of four held-out "
                   "strokes: glass misses, +0.45 dB over the ceiling (SE 0.04; as we read it, "
                   "its stick-slip rate, 20 /mm, sweeps the tangential tool mode at 280 Hz "
                   "inside the gap); "
                   "R1 meets it by 0.004 dB (+0.246, SE 0.08). Before session 14's hand 6 of 14 "
                   "missed (R1 +0.77, R2 +0.25, sandpaper_p320 +0.28, glass +0.49, corduroy "
                   "+0.26, sandpaper_p80 +2.60) (docs/texture.md, 'The hand's speed drift')")
def test_targets_on_four_strokes_per_texture_in_the_middle_of_a_gap(four_stroke_figures):
    misses = _mean_misses(four_stroke_figures[15.0])
    assert not misses, misses


@pytest.fixture(scope="module")
def identification(every_texture):
    models, scans = every_texture
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {m: identify(models, scans, method=m) for m in ("stretch", "lsf")}


def test_identification_is_well_above_chance(identification):
    for ident in identification.values():
        assert len(ident.labels) >= 12
        assert ident.rate >= 0.75  # a regression guard, not the target (below)


def test_identification_target_100_percent(identification):
    """Met with the default fit (the periodic surfaces' lines, the calibrated spectrum for
    the others), "stretch" and the third-octave band-level distance (identify's default):
    28 of 28 (14 textures at 15 and 30 mm/s), the closest call R1 at 30 mm/s against R2
    with a 219 % margin (session 14; before its hand R1 at 15 mm/s, also 219 %; 144 %
    with the base at 150 iterations; before the lines: R2 at 15 mm/s, 45 %; 28/28 and
    42/42 on two more sets, closest +244 % and +114 %). With the pooled fit also 28/28,
    the closest call mesh_steel at 15 mm/s, 47 % (62 % before session 14); with the 4
    Hz-bin LSD the pooled models' scans were 27/28 (session 14: sandpaper_p80 at 15 mm/s
    taken for brick) or 28/28 depending on the noise drawn; LSF 27/28 (26/28 before)
    (benchmarks/texture_causes.py identify 1 50 15,30; docs/texture.md)."""
    ident = identification["stretch"]
    assert len(ident.labels) >= 12
    missed = [(a["scan"], a["predicted"]) for a in ident.assignments
              if a["predicted"] != a["label"]]
    assert ident.rate == 1.0, missed


# ------------------------------------------------------------------ a light touch
LIGHT_LOAD = 0.3


@pytest.fixture(scope="module")
def light_touch_figures():
    """brick and sandpaper_p320 scanned with a light touch (``load_scale=0.3``: the tip
    is off the surface 2-35 % of the time at 30-40 mm/s, docs/texture.md "The scan
    generator"), fitted as every texture is (two 10 s strokes per speed, seeds 1-2),
    scored on the means of four held-out strokes at 30, 35 and 40 mm/s."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = _models(("brick", "sandpaper_p320"), LIGHT_LOAD)
    return {v: _mean_figures(models, v, load_scale=LIGHT_LOAD) for v in (30.0, 35.0, 40.0)}


def test_a_light_touch_meets_the_targets_with_the_tip_flying(light_touch_figures):
    """Impacts and all, on the means of four strokes at 30, 35 and 40 mm/s:
    sandpaper_p320 (in flight 2 %, 7 % and 16 % of the time) -0.09, -0.18, -0.42 dB over
    the ceiling, brick (12 %, 22 %, 35 %) -0.12, +0.16, -0.10 dB; correlation
    0.982-0.986 (measured). Brick at 35 mm/s missed until session 14's hand (+0.37 dB,
    SE 0.09, a strict xfail; +0.42 / +0.37 / +0.48 on 8 strokes with train seeds 1 / 5 /
    8)."""
    cells = [(v, n) for v in (30.0, 35.0, 40.0) for n in ("sandpaper_p320", "brick")]
    for v, name in cells:
        misses = _mean_misses({name: light_touch_figures[v][name]})
        assert not misses, (v, misses)

