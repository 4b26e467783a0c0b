"""``fydpad texture fit`` runs every family through the one ``Kind`` contract: a family
registered with the hooks gets them called in turn (option check against the scans'
rate, notes about the scans, fit, describe, the fit's report, plot), and a family whose
fit takes only flags refuses ``--set``."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture import operations
from fydpad.texture.families import KINDS
from fydpad.texture.family import FORMAT, Kind, mixed_surfaces
from fydpad.texture.scan_io import write_scan


def _scan(path: Path, surface: str) -> str:
    s = generate_scan("felt", 20.0, 1.0, seed=1)
    write_scan(path, s.t_s, s.acc, s.speed_mm_s, meta={"surface": surface})
    return str(path)


def _family(calls: list[str], **kw) -> Kind:
    def check(opts, fs_hz):
        calls.append(f"check {fs_hz:g}")
        if opts["level"] < 0:
            raise UserError("--level must be >= 0")

    def fit(scans, *, level, report):
        calls.append("fit")
        report([f"  chose level {level}"])
        return {"format": FORMAT, "kind": "toy", "level": level, "surface": scans[0].surface}

    def plot(path, scans, data, opts):
        calls.append("plot")
        Path(path).write_text(f"{data['level']} {len(scans)}")

    return Kind("toy", lambda data, where: None, fit, fit_options=("level", "report"),
                check_options=check, notes=mixed_surfaces, plot=plot,
                describe=lambda data, where: [f"toy at level {data['level']}"], **kw)


def test_every_hook_of_a_family_is_called_in_turn(tmp_path, monkeypatch):
    calls: list[str] = []
    monkeypatch.setitem(KINDS, "toy", _family(calls))
    scans = [_scan(tmp_path / "a.csv", "felt"), _scan(tmp_path / "b.csv", "cork")]
    out, fig = tmp_path / "m.json", tmp_path / "fig.txt"
    got = operations.fit_model("toy", scans, {"level": 3, "other": 1}, str(out), str(fig))
    assert calls == ["check 1000", "fit", "plot"]
    assert got.lines == [f"{out}: toy at level 3", "  chose level 3"]
    assert got.notes == ["the scans are of 2 surfaces (# surface=: felt (1), cork (1)), "
                         "pooled into one model labelled felt; fit each surface on its own, "
                         "or name the mix with --surface"]
    assert json.loads(out.read_text())["level"] == 3
    assert fig.read_text() == "3 2"
    with pytest.raises(UserError, match="--level must be >= 0"):
        operations.fit_model("toy", scans, {"level": -1}, str(tmp_path / "bad.json"))
    assert not (tmp_path / "bad.json").exists()


def test_set_goes_to_the_fit_unless_the_family_takes_only_flags(tmp_path, monkeypatch):
    calls: list[str] = []
    scans = [_scan(tmp_path / "a.csv", "felt")]
    monkeypatch.setitem(KINDS, "toy", _family(calls))
    got = operations.fit_model("toy", scans, {"level": 3}, str(tmp_path / "m.json"),
                               extra={"level": 5})
    assert got.lines[1] == "  chose level 5" and got.notes == []
    monkeypatch.setitem(KINDS, "toy", replace(KINDS["toy"], set_options=False))
    with pytest.raises(UserError, match=r"^--set level: the toy fit takes its options as "
                                        r"flags \(fit --help\)$"):
        operations.fit_model("toy", scans, {"level": 3}, str(tmp_path / "m.json"),
                             extra={"level": 5})
    with pytest.raises(UserError, match="the lpc fit takes its options as flags"):
        operations.fit_model("lpc", scans, {}, str(tmp_path / "m.json"), extra={"order": 3})


def test_plot_of_a_family_that_draws_none_is_refused_before_the_work(tmp_path, monkeypatch):
    calls: list[str] = []
    scans = [_scan(tmp_path / "a.csv", "felt")]
    monkeypatch.setitem(KINDS, "toy", replace(_family(calls), plot=None))
    with pytest.raises(UserError, match=r"^--plot \S+p\.png: the toy fit draws no figure"):
        operations.fit_model("toy", scans, {"level": 3}, str(tmp_path / "m.json"),
                             plot=str(tmp_path / "p.png"))
    assert calls == [] and not (tmp_path / "m.json").exists()
