"""Speed coverage: the speeds the scans went at, and the gaps where a model interpolates
(fydpad/texture/lpc/coverage.py), through the fit, the model file and the commands; and
``evaluate --second``, the ceiling a second recording sets."""

from __future__ import annotations

import json

import matplotlib.image as mpimg
import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.texture.evaluate import verdict_on_means
from fydpad.texture.lpc.coverage import (
    checked_spans,
    describe,
    gaps_within,
    inside,
    scanned_spans,
    speed_histogram,
    steady,
)
from fydpad.texture.lpc.model_file import load_model
from fydpad.texture.plots import SpeedCoverage, plot_spectra
from fydpad.texture.scan_generator import generate_scan, save_generated
from tests.texture_families.helpers import run_cli as run

FS = 1000.0


def test_a_hands_strokes_cover_their_wander_not_their_ramps():
    """Strokes at 10 and 40 mm/s (the generator's hand: a wander of 9 % RMS, 0.3 s
    ramps at each end through every slower speed). One stroke each, and 24 each: the
    ramps add 2-3 ms per 0.5 mm/s bin per stroke, so without the steady-speed rule 24
    strokes' ramps cover 15-30 mm/s (checked below); with it the gap stays. What lies
    between the ramps is covered (the wander's tails of one 4 s stroke spend under the
    0.1 s a bin needs: 95-98 % of it is)."""
    for strokes_per_speed in (1, 24):
        strokes = [generate_scan("felt", v, 4.0, seed=3 + k) for v in (10.0, 40.0)
                   for k in range(strokes_per_speed)]
        spans = scanned_spans([s.speed_mm_s for s in strokes], FS)
        assert len(spans) == 2, (strokes_per_speed, spans)
        for v, (lo, hi) in zip((10.0, 40.0), spans, strict=True):
            ramp = round(0.3 * FS)
            wander = np.concatenate([s.speed_mm_s[ramp:-ramp] for s in strokes
                                     if abs(np.median(s.speed_mm_s) - v) < 5])
            assert lo <= v <= hi
            assert np.mean((wander >= lo) & (wander <= hi)) > 0.93
        (gap,) = gaps_within(spans, 10.0, 40.0)  # 40 mm/s strokes wander down to ~30
        assert gap[0] < 15.0 and gap[1] > 25.0, gap
        assert inside(np.array([15.0, 20.0, 25.0]), [gap]).all()
    # The rule matters: counting every sample, the 24 strokes' ramps fill the gap.
    every = np.concatenate([s.speed_mm_s for s in strokes])
    edges, _ = speed_histogram([every], FS)
    counts, _ = np.histogram(every[np.isfinite(every)], edges)
    assert np.all(counts[(edges[:-1] >= 15) & (edges[:-1] < 30)] >= 0.1 * FS)


def test_steady_is_the_wander_not_the_ramp():
    s = generate_scan("cork", 20.0, 6.0, seed=1)
    ok = steady(s.speed_mm_s, FS)
    assert ok[1000:-1000].all()  # the hand's wander
    ramp = s.speed_mm_s < 0.8 * np.median(s.speed_mm_s)
    ramp[2000:-2000] = False
    assert ramp.sum() > 50 and not ok[ramp].any()


def test_spans_bridge_one_bin_and_ignore_rest_lost_tracks_and_the_range_end():
    def hold(v, n=500):
        return np.full(n, float(v))

    # 10-10.5 and 11-11.5: a one-bin hole, bridged; 12.5 is two bins from 11.5: a gap.
    v = np.concatenate([hold(10.2), hold(11.2), hold(12.7), [np.nan] * 3000, hold(0.7),
                        hold(0.0), hold(20.1)])
    assert scanned_spans([v], FS) == [(10.0, 11.5), (12.5, 13.0), (20.0, 20.5)]
    assert gaps_within(scanned_spans([v], FS), 10.0, 20.0) == [(11.5, 12.5), (13.0, 20.0)]
    assert scanned_spans([hold(10.0, 50)], FS) == []  # 50 ms is not a scan
    assert scanned_spans([hold(45.0)], FS, (5.0, 45.0)) == []  # the range is lo <= v < hi
    assert scanned_spans([hold(44.9)], FS, (5.0, 45.0)) == [(44.5, 45.0)]
    assert scanned_spans([], FS) == [] and scanned_spans([[np.nan]], FS) == []
    assert scanned_spans([np.linspace(5, 40, 4000)], FS) == []  # 8.75 mm/s/s at 5 mm/s
    edges, sec = speed_histogram([np.r_[hold(10.0), 1e11]], FS)  # a corrupt sample
    assert edges[-1] < 100 and sec.sum() == pytest.approx(0.5 - 0.1, abs=0.02)
    # No span at all: the whole fitted range is a gap; edge pieces under 1 mm/s are not.
    assert gaps_within([], 10.0, 40.0) == [(10.0, 40.0)]
    assert gaps_within([(10.5, 39.5)], 10.0, 40.0) == []
    assert describe([]) == "none" and describe([(12.5, 17.5)]) == "12.5-17.5 mm/s"


@pytest.mark.parametrize("bad", [[[17.5, 12]], [[1, 2, 3]], "12-17", [["12"]], {"12": 1},
                                 [["1", "2"]], [[True, 2]], [[-1, 2]], [[10, 20], [15, 30]],
                                 [[20, 30], [10, 15]], [[0, float("nan")]]])
def test_malformed_spans_are_refused_naming_file_and_key(bad):
    with pytest.raises(UserError, match=r"m\.json: provenance\.interpolated_mm_s must be"):
        checked_spans(bad, "m.json", "interpolated_mm_s")


def test_model_file_with_malformed_coverage_is_refused_on_reading(tmp_path, felt):
    d = json.loads((felt / "felt.json").read_text())
    d["provenance"]["speed_coverage_mm_s"] = [[12, "x"]]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(UserError, match=r"bad\.json: provenance\.speed_coverage_mm_s"):
        load_model(bad)


@pytest.fixture(scope="module")
def felt(tmp_path_factory):
    """Strokes over felt at 10, 20 and 30 mm/s, and a model fitted on the 10 and 30 mm/s
    ones (order 60): felt.json."""
    d = tmp_path_factory.mktemp("coverage")
    assert run("generate-scans", "--out-dir", str(d), "--textures", "felt", "--speeds",
               "10,20,30", "--strokes", "1", "--seconds", "6") == 0
    assert run("fit", str(d / "felt_10mms_s1.csv"), str(d / "felt_30mms_s1.csv"),
               "--out", str(d / "felt.json"), "--speeds", "10,30", "--order", "60",
               "--form", "calibrated") == 0
    return d


def test_fit_records_and_says_where_it_interpolates(felt, tmp_path, capsys):
    out = tmp_path / "felt.json"
    assert run("fit", str(felt / "felt_10mms_s1.csv"), str(felt / "felt_30mms_s1.csv"),
               "--out", str(out), "--speeds", "10,30", "--order", "60",
               "--form", "calibrated") == 0
    said = capsys.readouterr().out
    prov = json.loads(out.read_text())["provenance"]
    gaps = [tuple(g) for g in prov["interpolated_mm_s"]]
    # The 30 mm/s stroke wanders down to ~23 mm/s; a hole in its wander is a gap too.
    widest = max(gaps, key=lambda g: g[1] - g[0])
    assert widest[0] < 15.0 and widest[1] > 20.0, gaps
    assert len(prov["speed_coverage_mm_s"]) == len(gaps) + 1
    assert "no scan between" in said and describe(gaps) in said
    middles = ", ".join(f"{round(a + b) / 2:g}" for a, b in gaps)  # each gap's middle
    assert f"scan strokes at {middles} mm/s" in said, said


def test_synth_and_evaluate_say_when_they_are_in_a_gap(felt, tmp_path, capsys):
    model = felt / "felt.json"
    capsys.readouterr()
    assert run("synth", str(model), "--speed-mm-s", "20", "--seconds", "0.2",
               "--out", str(tmp_path / "a.csv")) == 0
    assert "no scan went at 20 mm/s" in capsys.readouterr().err
    # The family path (a channel named, a WAV file) says it too.
    assert run("synth", str(model), "--speed-mm-s", "20", "--seconds", "0.2",
               "--channel", "vibration", "--out", str(tmp_path / "a.wav")) == 0
    assert "no scan went at 20 mm/s" in capsys.readouterr().err
    assert run("synth", str(model), "--speed-mm-s", "10", "--seconds", "0.2",
               "--out", str(tmp_path / "b.csv")) == 0
    assert "no scan went" not in capsys.readouterr().err
    share = {}
    for v in (10, 20):
        j = tmp_path / f"e{v}.json"
        assert run("evaluate", str(model), str(felt / f"felt_{v}mms_s1.csv"),
                   "--json", str(j)) == 0
        share[v] = json.loads(j.read_text())["interpolated_share"]
    # The 20 mm/s stroke is all gap but for its ramps; the 10 mm/s one is the fit's own.
    assert share[20] > 0.8 and share[10] < 0.1, share
    assert "the model interpolates there" in capsys.readouterr().out


def test_a_model_from_before_coverage_reads_as_unknown(felt, tmp_path, capsys):
    d = json.loads((felt / "felt.json").read_text())
    for key in ("speed_coverage_mm_s", "interpolated_mm_s"):
        del d["provenance"][key]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(d))
    j = tmp_path / "e.json"
    assert run("evaluate", str(old), str(felt / "felt_20mms_s1.csv"), "--json", str(j)) == 0
    assert json.loads(j.read_text())["interpolated_share"] is None
    assert "interpolates" not in capsys.readouterr().out
    assert run("synth", str(old), "--speed-mm-s", "20", "--seconds", "0.2",
               "--out", str(tmp_path / "a.csv")) == 0


def test_the_fit_plot_has_a_coverage_panel(tmp_path):
    f = np.linspace(20, 500, 50)
    panels = [(f"{v} mm/s", f, np.ones(50), np.ones(50)) for v in (10, 30)]
    cov = SpeedCoverage(np.arange(0, 45.5, 0.5), np.r_[np.zeros(16), np.ones(74)],
                        [10.0, 30.0], [(12.0, 27.0)])
    heights = [mpimg.imread(plot_spectra(tmp_path / f"{k}.png", panels, coverage=c)).shape[0]
               for k, c in (("plain", None), ("coverage", cov))]
    assert heights[1] == 2 * heights[0]  # one more row of panels, the spectra's height


def test_evaluate_against_a_second_recording(felt, tmp_path, capsys):
    """--second: the ceiling and the targets' verdict. Ground truth: the scan as its own
    second recording is a ceiling of 0 dB and correlation 1; another stroke of felt is
    a ceiling above 0; the verdict is the targets' rule on the printed figures."""
    model, scan = str(felt / "felt.json"), str(felt / "felt_10mms_s1.csv")
    other = tmp_path / "felt_10_b.csv"
    save_generated(generate_scan("felt", 10.0, 6.0, seed=7), other)
    figures = {}
    for name, second in (("self", scan), ("other", str(other))):
        j = tmp_path / f"{name}.json"
        assert run("evaluate", model, scan, "--second", second, "--json", str(j),
                   "--plot", str(tmp_path / f"{name}.png")) == 0
        figures[name] = json.loads(j.read_text())
        assert (tmp_path / f"{name}.png").stat().st_size > 1000
    own = figures["self"]["ceiling"]
    assert own["lsd_db"] == 0.0 and own["psd_correlation"] == pytest.approx(1.0)
    for e in figures.values():
        assert e["lsd_over_ceiling_db"] == pytest.approx(e["lsd_db"] - e["ceiling"]["lsd_db"])
        assert e["targets_met"] == (e["psd_correlation"] >= 0.95
                                    and e["lsd_over_ceiling_db"] <= 0.25)
    assert 0.2 < figures["other"]["ceiling"]["lsd_db"] < 3.0
    assert "targets" in capsys.readouterr().out


def test_evaluate_several_scans_judges_the_targets_on_the_means(felt, tmp_path, capsys):
    """Several scans, one second recording each: every scan's figures as alone, their
    means, and the targets' rule applied to the means over the pairs with a fair ceiling
    (a second recording of cork sets none and is left out of the verdict)."""
    model = str(felt / "felt.json")
    paths = {}
    for name, surface, seed in (("a2", "felt", 8), ("b1", "felt", 7), ("b2", "felt", 9),
                                ("c1", "felt", 10), ("cork", "cork", 11)):
        paths[name] = tmp_path / f"{name}.csv"
        save_generated(generate_scan(surface, 10.0, 6.0, seed=seed), paths[name])
    scans = [str(felt / "felt_10mms_s1.csv"), str(paths["a2"]), str(paths["c1"])]
    seconds = [str(paths["b1"]), str(paths["b2"]), str(paths["cork"])]
    alone = []
    for i, (scan, second) in enumerate(zip(scans, seconds, strict=True)):
        j = tmp_path / f"alone{i}.json"
        assert run("evaluate", model, scan, "--second", second, "--json", str(j),
                   "--seed", str(i)) == 0  # the i-th of several scans draws seed i
        alone.append(json.loads(j.read_text()))
    j = tmp_path / "all.json"
    capsys.readouterr()
    assert run("evaluate", model, *scans, *(x for p in seconds for x in ("--second", p)),
               "--json", str(j), "--plot", str(tmp_path / "all.png")) == 0
    said = capsys.readouterr().out
    e = json.loads(j.read_text())
    assert [s["scan"] for s in e["scans"]] == scans
    for got, want in zip(e["scans"], alone, strict=True):
        assert got["lsd_db"] == pytest.approx(want["lsd_db"])
        assert got["targets_met"] == want["targets_met"]
    m = e["mean"]
    assert m["lsd_db"] == pytest.approx(np.mean([a["lsd_db"] for a in alone]))
    fair = alone[:2]
    assert alone[2]["targets_met"] is None and m["fair_pairs"] == 2
    ceil = np.mean([a["ceiling"]["lsd_db"] for a in fair])
    assert m["ceiling_lsd_db"] == pytest.approx(ceil)
    assert m["lsd_over_ceiling_db"] == pytest.approx(np.mean([a["lsd_db"] for a in fair])
                                                     - ceil)
    corr = np.mean([a["psd_correlation"] for a in fair])
    assert m["targets_met"] == (corr >= 0.95 and m["lsd_over_ceiling_db"] <= 0.25)
    gaps = [a["lsd_over_ceiling_db"] for a in fair]
    assert m["lsd_over_ceiling_se_db"] == pytest.approx(np.std(gaps, ddof=1) / np.sqrt(2))
    v = verdict_on_means([a["psd_correlation"] for a in fair], gaps)
    assert m["verdict_decided"] == v.decided
    assert ("more strokes would decide it" in said) == (not v.decided)
    assert "on the means of the 2 scan(s) with a fair ceiling" in said
    assert (tmp_path / "all.png").stat().st_size > 1000
    with pytest.raises(UserError, match=r"--second: 1 recording\(s\) for 3 scan\(s\)"):
        run("evaluate", model, *scans, "--second", seconds[0])
    # One scan, --second before it: the order of the options does not matter.
    j1 = tmp_path / "order.json"
    assert run("evaluate", model, "--second", seconds[0], scans[0], "--json", str(j1)) == 0
    assert json.loads(j1.read_text())["lsd_db"] == pytest.approx(alone[0]["lsd_db"])


@pytest.mark.parametrize("corr, gap, met, decided", [
    ([0.99, 0.98, 0.99, 0.98], [0.00, 0.05, -0.05, 0.02], True, True),   # clear
    ([0.99, 0.98, 0.99, 0.98], [0.60, -0.40, 0.50, -0.30], True, False),  # +0.10 +- 0.25
    ([0.99, 0.98, 0.99, 0.98], [0.90, 0.80, 0.85, 0.95], False, True),   # LSD clearly over
    # The correlation clearly under while the LSD sits near its limit: a decided miss.
    ([0.80, 0.81, 0.79, 0.80], [0.20, 0.30, 0.15, 0.15], False, True),
    ([0.97, 0.93, 0.96, 0.92], [0.0, 0.0, 0.0, 0.0], False, False),      # corr 0.945 +- 0.01
    ([0.99], [0.1], True, False),                                         # one stroke
])
def test_verdict_on_means(corr, gap, met, decided):
    v = verdict_on_means(corr, gap)
    assert (v.met, v.decided) == (met, decided), v
    assert v.lsd_over_ceiling_db == pytest.approx(np.mean(gap))


def test_evaluate_second_recording_errors(felt, tmp_path):
    model, scan = str(felt / "felt.json"), str(felt / "felt_10mms_s1.csv")
    slow = tmp_path / "felt_500hz.csv"
    save_generated(generate_scan("felt", 10.0, 6.0, seed=7, fs_hz=500.0), slow)
    with pytest.raises(UserError, match=r"felt_500hz\.csv: column 't_s': sample rate 500 Hz"):
        run("evaluate", model, scan, "--second", str(slow))
    fast = tmp_path / "felt_90.csv"  # only its ramps pass through the model's speeds
    save_generated(generate_scan("felt", 90.0, 4.0, seed=7), fast)
    with pytest.raises(UserError, match=r"felt_90\.csv: \d+ of its 4000 samples are within "
                       r"the model's speeds \(column 'speed_mm_s'\), in no run of the 250"):
        run("evaluate", model, scan, "--second", str(fast))


@pytest.mark.parametrize("what, second, note", [
    ("another surface", ("cork", 10.0, 6.0), "it is of 'cork', the scan of 'felt'"),
    ("another speed", ("felt", 30.0, 6.0), "median speed"),
    ("much shorter", ("felt", 10.0, 1.5), "less than half the scan's"),
])
def test_an_unfair_second_recording_gives_no_verdict(felt, tmp_path, capsys, what, second,
                                                     note):
    """A ceiling from another surface, another speed (both within the model's speeds) or
    a much shorter recording is far above what a fair one is (19 dB for felt at 30 mm/s
    against a scan at 10): any model would 'meet' it. The figures are written, the
    verdict is null, and the reason is said."""
    name, v, seconds = second
    path = tmp_path / f"{name}_{v:g}_{seconds:g}.csv"
    save_generated(generate_scan(name, v, seconds, seed=7), path)
    j = tmp_path / "e.json"
    capsys.readouterr()
    assert run("evaluate", str(felt / "felt.json"), str(felt / "felt_10mms_s1.csv"),
               "--second", str(path), "--json", str(j)) == 0
    e = json.loads(j.read_text())
    assert e["targets_met"] is None and note in e["ceiling_note"], (what, e)
    assert "no verdict" in capsys.readouterr().out
    assert e["second_surface"] == name and e["second_seconds"] > 0


def test_run_says_where_the_texture_is_interpolated(felt, capsys):
    """`fydpad run --texture` (the station, synthetic finger, simulated motors, 0.2 s):
    one line at start names the gaps."""
    from fydpad.cli import main

    assert main(["run", "--synthetic", "circle", "--motors", "sim", "--texture",
                 str(felt / "felt.json"), "--duration", "0.2", "--as-fast-as-possible",
                 "--no-realtime"]) == 0
    err = capsys.readouterr().err
    gaps = json.loads((felt / "felt.json").read_text())["provenance"]["interpolated_mm_s"]
    assert f"no scan between {describe([tuple(g) for g in gaps])}" in err
