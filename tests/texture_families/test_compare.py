"""The cross-family comparison: a confusion matrix per family on the same textures, and
Bianchi 2015's 2 x 2 (SS1..SS4) with the softness rendered through the simulated fabric."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from fydpad.specimen_experiment import specimen_experiment
from fydpad.synth.texture_scans import generate_scan, save_generated
from fydpad.texture.evaluation.identify import (
    by_surface,
    compare_families,
    fit_per_surface,
    shape_distance_db,
)
from tests.texture_families.helpers import run_cli

NAMES = ("R1", "R2", "canvas", "cork", "felt")


@pytest.fixture(scope="module")
def scans():
    train = [generate_scan(n, 20.0, 4.0, seed=1, friction=True) for n in NAMES]
    test = [generate_scan(n, 20.0, 4.0, seed=s, friction=True) for n in NAMES
            for s in (101, 102)]
    return train, test


def test_confusion_per_family_on_the_same_scans(scans):
    train, test = scans
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = {k: ident for k, (ident, _) in
               compare_families(train, test, ["lpc", "friction", "grating"]).items()}
    for kind in ("lpc", "friction", "grating"):
        c = np.asarray(res[kind].confusion)
        assert c.sum() == len(test) and res[kind].labels[:len(NAMES)] == list(NAMES)
    assert res["lpc"].rate >= 0.9
    assert res["friction"].rate >= 0.7
    # A grating model tells the two gratings apart (its own lambda), not the rest.
    g = np.asarray(res["grating"].confusion)
    assert g[0, 0] == 2 and g[1, 1] == 2


def test_specimens_need_the_stiffness_feature(scans):
    """Spectra alone cannot tell SS1 from SS3 (both R1) or SS2 from SS4; a simulated
    press on the fabric holding each specimen's stiffness can."""
    train, test = scans
    te = by_surface(test)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models, labels = fit_per_surface("lpc", by_surface(train[:2]))  # R1, R2
        fam = dict(zip(labels, models, strict=True))
        r = specimen_experiment("lpc", fam, te, te, trials=2)
        again = specimen_experiment("lpc", fam, te, te, trials=2)
    # Seeded: the same seed gives the same spectral distances, trial by trial.
    assert [row["spectral_distance_db"] for row in again["rows"]] == \
        [row["spectral_distance_db"] for row in r["rows"]]
    spec = np.asarray(r["confusion"]["spectra"])
    assert r["specimens"] == ["SS1", "SS2", "SS3", "SS4"]
    # Roughness right every time, softness by chance: SS1 and SS3 land on one column.
    rough = np.array([0, 1, 0, 1])
    for i in range(4):
        assert spec[i, rough != rough[i]].sum() == 0
    assert r["rate"]["spectra"] <= 0.5 + 1e-9
    assert r["rate"]["spectra+stiffness"] == 1.0
    ks = {row["specimen"]: row["k_measured_n_per_mm"] for row in r["rows"]}
    assert ks["SS1"] == pytest.approx(0.88, rel=0.1) and ks["SS3"] == pytest.approx(0.39,
                                                                                   rel=0.1)


def test_shape_distance_ignores_level_and_tilt_not_lines():
    f = np.linspace(20, 500, 200)
    base = 1.0 + 50 * (np.abs(f - 100) < 3)
    assert shape_distance_db(base, 7 * base * f ** 2, f) < 1e-9
    assert shape_distance_db(base, 1.0 + 50 * (np.abs(f - 130) < 3), f) > 2.0


def test_cli_compare_writes_json_and_plots(scans, tmp_path):
    train, test = scans
    paths = {}
    for tag, group in (("tr", train[:2]), ("te", test[:4])):
        d = tmp_path / tag
        d.mkdir()
        paths[tag] = [str(save_generated(s, d / f"{s.surface}_{k}.csv"))
                      for k, s in enumerate(group)]
    assert run_cli("compare", "--train", *paths["tr"], "--scans", *paths["te"], "--kinds",
                   "lpc,grating", "--out-dir", str(tmp_path / "out")) == 0
    res = json.loads((tmp_path / "out" / "compare.json").read_text())
    assert set(res["families"]) == {"lpc", "grating"}
    assert (tmp_path / "out" / "confusion_lpc.png").stat().st_size > 5000
    # Reproducible: the LPC models' noise comes from --seed (default 0).
    assert run_cli("compare", "--train", *paths["tr"], "--scans", *paths["te"], "--kinds",
                   "lpc", "--seed", "0", "--out-dir", str(tmp_path / "again")) == 0
    again = json.loads((tmp_path / "again" / "compare.json").read_text())
    assert again["families"]["lpc"] == res["families"]["lpc"]


def test_cli_identify_with_one_family_and_refuses_mixed_kinds(scans, tmp_path):
    train, test = scans
    models = []
    for s in train[:2]:  # R1, R2
        p = str(save_generated(s, tmp_path / f"{s.surface}_train.csv"))
        out = str(tmp_path / f"{s.surface}_friction.json")
        assert run_cli("fit", "--kind", "friction", p, "--out", out) == 0
        models.append(out)
    test_paths = [str(save_generated(s, tmp_path / f"{s.surface}_{k}.csv"))
                  for k, s in enumerate(test[:4])]
    assert run_cli("identify", *models, "--scans", *test_paths, "--json",
                   str(tmp_path / "i.json")) == 0
    res = json.loads((tmp_path / "i.json").read_text())
    assert res["kind"] == "friction" and res["rate"] == 1.0
    assert run_cli("fit", "--kind", "grating", "--wavelength-mm", "2", "--out",
                   str(tmp_path / "g.json")) == 0
    from fydpad.errors import UserError

    with pytest.raises(UserError, match="mix kinds"):
        run_cli("identify", models[0], str(tmp_path / "g.json"), "--scans", test_paths[0])


def test_the_same_seed_gives_the_same_confusion_another_seed_other_draws(scans):
    """The LPC family synthesizes noise: identify_families draws it from its seed, so two
    runs agree to the digit, and another seed gives other distances (the seed reaches
    the synthesis)."""
    from fydpad.texture.evaluation.identify import identify_families

    train, test = scans
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models, labels = fit_per_surface("lpc", by_surface(train[:3]))
        runs = [identify_families(models, labels, test[:4], seed=s) for s in (5, 5, 6)]
    dist = [[a["shape_distance_db"] for a in r.assignments] for r in runs]
    assert dist[0] == dist[1]
    assert dist[0] != dist[2]


def test_specimens_without_r1_r2_refused_before_any_fit(scans, tmp_path, monkeypatch):
    """The 2 x 2 needs R1 and R2 among both the training and the test scans: the command
    says so before it fits any family."""
    import fydpad.texture.evaluation.identify as identify
    from fydpad.errors import UserError

    fits = []
    monkeypatch.setattr(identify, "fit_per_surface", lambda *a, **k: fits.append(a))
    train, test = scans
    felt = [str(save_generated(s, tmp_path / f"{s.surface}_{k}.csv"))
            for k, s in enumerate([train[4], test[8]])]
    r1 = str(save_generated(train[0], tmp_path / "R1.csv"))
    with pytest.raises(UserError, match="need R1 and R2 scans"):
        run_cli("compare", "--train", r1, felt[0], "--scans", felt[1], "--kinds", "lpc",
                "--specimens", "--out-dir", str(tmp_path / "out"))
    assert fits == []
