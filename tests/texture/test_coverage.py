"""Speed coverage: the speeds the scans went at, and the gaps where a model interpolates
(fydpad/texture/coverage.py), through the fit, the model file and the commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.texture.coverage import (
    describe,
    gaps_between,
    inside,
    model_gaps,
    scanned_spans,
)
from fydpad.texture.scan_generator import generate_scan
from tests.texture_families.helpers import run_cli as run

FS = 1000.0


def test_a_hands_strokes_cover_their_wander_not_their_ramps():
    """Strokes at 10 and 40 mm/s (the generator's hand: a wander of a few mm/s, ramps of
    0.25 s at each end). The ramps pass through every slower speed in a few ms per 0.5
    mm/s bin, so 15-35 mm/s is a gap; each stroke's median speed is covered."""
    strokes = [generate_scan("felt", v, 8.0, seed=3) for v in (10.0, 40.0)]
    spans = scanned_spans([s.speed_mm_s for s in strokes], FS)
    assert len(spans) == 2, spans
    for s, (lo, hi) in zip(strokes, spans, strict=True):
        v = s.speed_mm_s
        assert lo <= np.median(v) <= hi
        # Most of the stroke is inside its span; the span is the wander, not the ramp.
        assert np.mean((v >= lo) & (v <= hi)) > 0.9
        assert hi - lo < 15.0
    (gap,) = gaps_between(spans)
    assert gap[0] < 15.0 and gap[1] > 35.0, gap
    # The ramp of the 40 mm/s stroke reached 20-30 mm/s, yet no time was spent there.
    ramp = strokes[1].speed_mm_s
    assert np.any((ramp > 20) & (ramp < 30))
    assert inside(np.array([20.0, 25.0, 30.0]), [gap]).all()


def test_spans_ignore_lost_tracks_and_bridge_narrow_gaps():
    v = np.concatenate([np.full(500, 10.2), np.full(500, 11.2), [np.nan] * 3000,
                        np.zeros(2000), np.full(500, 20.1)])
    # 10-10.5 and 11-11.5 are 0.5 mm/s apart: bridged; NaN and standstill are no speed.
    assert scanned_spans([v], FS) == [(10.0, 11.5), (20.0, 20.5)]
    assert scanned_spans([np.full(50, 10.0)], FS) == []  # 50 ms: not scanned
    assert scanned_spans([], FS) == [] and scanned_spans([[np.nan]], FS) == []
    assert describe([]) == "none" and describe([(12.5, 17.5)]) == "12.5-17.5 mm/s"


def test_model_gaps_are_checked():
    assert model_gaps({}) == []
    assert model_gaps({"interpolated_mm_s": [[12, 17.5]]}) == [(12.0, 17.5)]
    for bad in ([[17.5, 12]], [[1, 2, 3]], "12-17", [[0, float("nan")]], [["a", 1]]):
        with pytest.raises(UserError, match=r"m\.json: provenance\.interpolated_mm_s"):
            model_gaps({"interpolated_mm_s": bad}, "m.json")


@pytest.fixture(scope="module")
def felt(tmp_path_factory):
    """Strokes over felt at 10, 20 and 30 mm/s, and a model fitted on the 10 and 30 mm/s
    ones (order 60): felt.json."""
    d = tmp_path_factory.mktemp("coverage")
    assert run("generate-scans", "--out-dir", str(d), "--textures", "felt", "--speeds",
               "10,20,30", "--strokes", "1", "--seconds", "6") == 0
    assert run("fit", str(d / "felt_10mms_s1.csv"), str(d / "felt_30mms_s1.csv"),
               "--out", str(d / "felt.json"), "--speeds", "10,30", "--order", "60") == 0
    return d


def test_fit_records_and_says_where_it_interpolates(felt, tmp_path, capsys):
    out = tmp_path / "felt.json"
    assert run("fit", str(felt / "felt_10mms_s1.csv"), str(felt / "felt_30mms_s1.csv"),
               "--out", str(out), "--speeds", "10,30", "--order", "60") == 0
    said = capsys.readouterr().out
    prov = json.loads(out.read_text())["provenance"]
    (gap,) = prov["interpolated_mm_s"]
    assert gap[0] < 15.0 and gap[1] > 25.0
    assert len(prov["speed_coverage_mm_s"]) == 2
    assert "no scan between" in said and describe([gap]) in said


def test_synth_and_evaluate_say_when_they_are_in_a_gap(felt, tmp_path, capsys):
    model = felt / "felt.json"
    capsys.readouterr()
    assert run("synth", str(model), "--speed-mm-s", "20", "--seconds", "0.2",
               "--out", str(tmp_path / "a.csv")) == 0
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
