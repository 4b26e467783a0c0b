"""The logic behind the web view's flows: the calibration's press collector,
the staircase session and its log, the experiment's stimuli file, and the render chain
switching texture models live (the simulated motors, in-process)."""

from __future__ import annotations

import io
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main as cli_main
from fydpad.errors import UserError
from fydpad.web.calibration import PressCollector
from fydpad.web.experiment import ExperimentError
from fydpad.web.staircase import StaircaseSession
from fydpad.web.stimuli import experiment_stimuli, load_stimuli
from vision.calibration import default_targets_mm
from vision.mapping import flip_point, workspace_to_roi

ROI, WS, FLIP, SIZE = (24, 22, 592, 414), (100.0, 70.0), "horizontal", (640, 480)


def _feed_presses(col: PressCollector, points_mm, t0: float = 0.0, hold_s: float = 0.8,
                  fps: float = 30.0, gap_s: float = 0.5) -> float:
    """Presses at ``points_mm`` as the tracker reports them (flipped-frame pixels)."""
    t = t0
    for x, y in points_mm:
        u, v = (float(a) for a in workspace_to_roi(x, y, ROI, WS))
        for _ in range(round(hold_s * fps)):
            col.feed(t, True, u, v)
            t += 1 / fps
        for _ in range(round(gap_s * fps)):
            col.feed(t, False, math.nan, math.nan)
            t += 1 / fps
    return t


def test_collector_waits_for_clear_fabric_then_fits_the_true_mapping():
    col = PressCollector.for_workspace(WS)
    targets = default_targets_mm(WS)
    # A finger already down when the flow starts, and short gaps: not yet clear.
    t = _feed_presses(col, targets[4:6], gap_s=0.5)
    assert col.state == "clear" and col.presses_px == []
    for _ in range(40):  # 1.3 s clear
        col.feed(t, False, math.nan, math.nan)
        t += 1 / 30
    assert col.state == "press"
    _feed_presses(col, targets[:3], t0=t)
    assert col.next_index == 3 and col.state == "press"
    with pytest.raises(ValueError, match="3 of 9 points"):
        col.fit(FLIP, SIZE, None)
    _feed_presses(col, targets[3:], t0=t + 10)
    assert col.state == "done"
    hom, residual = col.fit(FLIP, SIZE, None)
    assert residual.max() < 0.05
    # Ground truth: a raw pixel maps to the workspace as the flip and the ROI say.
    from vision.calibration import apply_homography

    for x, y in [(-45.0, -30.0), (12.0, 7.5), (44.0, 31.0)]:
        u, v = (float(a) for a in workspace_to_roi(x, y, ROI, WS))
        raw = np.array([flip_point(u, v, FLIP, SIZE)])
        got = apply_homography(hom.h, raw)[0]
        assert math.hypot(got[0] - x, got[1] - y) < 0.05


def test_collector_ignores_short_presses_and_repeated_frames():
    col = PressCollector.for_workspace(WS, min_hold_s=0.4)
    for k in range(40):
        col.feed(k / 30, False, math.nan, math.nan)
    t = _feed_presses(col, [(0.0, 0.0)], t0=2.0, hold_s=0.2)
    assert col.short_presses == 1 and col.next_index == 0
    col.feed(t - 1.0, True, 100.0, 100.0)  # an old frame: ignored
    assert col.next_index == 0 and not col.status()["pressing"]


def test_staircase_session_logs_like_the_command_and_resumes(tmp_path: Path, monkeypatch,
                                                             capsys):
    answers = ["r", "r", "v", "v", "r", "v", "r", "v", "r"]  # the 6th reversal ends it
    applied: list[float] = []
    s = StaircaseSession.open(tmp_path, "P1", present=applied.append)
    for a in answers[:5]:
        s.answer(a)
    # The station applied each trial's b live, starting at 400.
    assert applied == [400, 410, 420, 410, 400, 410]
    with pytest.raises(ExperimentError, match="current trial is 6"):
        s.answer("r", trial=5)
    # A crash halfway through writing an answer: the torn line is dropped on resume.
    with s.log_path.open("a") as fh:
        fh.write("6,41")
    s2 = StaircaseSession.open(tmp_path, "P1")
    assert s2.stairs.trials == 5 and s2.stairs.b == 410
    for a in answers[5:]:
        s2.answer(a)
    assert s2.stairs.done and s2.status()["result"] == s2.stairs.result
    # The terminal command reads the same log (and finds it complete).
    expected = tmp_path / "cmd.csv"
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n".join(answers) + "\n"))
    assert cli_main(["texture", "staircase", "--log", str(expected)]) == 0
    assert s2.log_path.read_text() == expected.read_text()
    out = capsys.readouterr().out
    assert f"b = {s2.stairs.result:g}" in out
    with pytest.raises(ExperimentError, match="complete"):
        s2.answer("r")


def test_staircase_refuses_a_log_of_another_start(tmp_path: Path):
    s = StaircaseSession.open(tmp_path, "P2")
    s.answer("real")
    with pytest.raises(ExperimentError, match="line 2: column 'b'"):
        StaircaseSession.open(tmp_path, "P2", start=300.0)


def test_stimuli_file_errors_name_the_entry_and_key(tmp_path: Path):
    f = tmp_path / "stimuli.json"
    f.write_text(json.dumps([{"name": "A", "stiffness_n_per_mm": 0.5},
                             {"name": "B", "stiffness_n_per_mm": -1}]))
    with pytest.raises(UserError, match=r"stimulus 2: key 'stiffness_n_per_mm'"):
        load_stimuli(f)
    f.write_text(json.dumps([{"name": "A", "stiffness_n_per_mm": 0.5, "texture": "nope.json"},
                             {"name": "B", "stiffness_n_per_mm": 1}]))
    with pytest.raises(UserError, match=r"nope\.json: missing"):
        load_stimuli(f)
    f.write_text(json.dumps([{"name": "A", "stiffness_n_per_mm": 0.5, "colour": 1},
                             {"name": "B", "stiffness_n_per_mm": 1}]))
    with pytest.raises(UserError, match="stimulus 1: unknown key 'colour'"):
        load_stimuli(f)


def _spatial_fit(vib: np.ndarray, x: np.ndarray, period_mm: float, bins: int = 40) -> float:
    """Share of the vibration's variance explained by its mean over the phase x mod period:
    near 1 for a signal periodic in x with that period."""
    phase = np.floor(np.mod(x, period_mm) / period_mm * bins).astype(int)
    means = np.bincount(phase, vib, bins) / np.maximum(np.bincount(phase, None, bins), 1)
    return 1.0 - np.var(vib - means[phase]) / np.var(vib)


def test_drive_chain_switches_textures_live(tmp_path: Path):
    """The paper's stimuli's grating models, loaded at start and selected by index: each
    renders its own spatial period; -1 renders nothing; b reaches a friction model."""
    from fydpad.config import StationConfig
    from fydpad.station.render import RenderSpec, build_chain

    stimuli = experiment_stimuli(None, tmp_path)
    textures = tuple(dict.fromkeys(s.texture for s in stimuli))
    assert [s.grating_mm for s in stimuli] == [3.9, 2.15, 3.9, 2.15]
    friction = tmp_path / "friction.json"
    friction.write_text(json.dumps({
        "format": "fydpad-texture-model", "kind": "friction", "format_version": 1,
        "mu": list(0.5 + 0.2 * np.sin(np.linspace(0, 2 * np.pi, 200, endpoint=False))),
        "dx_mm": 0.05, "x0_mm": 0.0}))
    chain = build_chain(RenderSpec(motors="sim", texture=str(friction), textures=textures,
                                   config=StationConfig(), realtime=False))
    assert chain.outputs[-1] == "texture"
    fits = {}
    for index in (1, 2, -1):
        chain.apply_control(index, math.nan)
        t = np.arange(3000) / 1000
        x = -30.0 + 20.0 * t  # 20 mm/s along x
        out = np.array([chain.tick(ti, True, xi, 0.0, 20.0, 1.0, 1.0, 0.6)
                        for ti, xi in zip(t, x, strict=True)])
        assert np.all(out[:, -1] == index)  # the log's texture column
        vib = out[500:, 0]
        if index == -1:
            assert np.all(vib == 0.0)
            continue
        fits[index] = {lam: _spatial_fit(vib, x[500:], lam) for lam in (3.9, 2.15)}
    assert fits[1][3.9] > 0.95 and fits[1][2.15] < 0.5
    assert fits[2][2.15] > 0.95 and fits[2][3.9] < 0.5
    live = chain.live_stats()
    assert live["index"] == -1 and live["switches"] == 3
    chain.apply_control(0, 333.0)
    assert chain.live_stats()["kind"] == "friction"
    assert chain.live_stats()["friction_b_v"] == 333.0
    chain.safe_stop()


def _friction_file(path: Path) -> Path:
    path.write_text(json.dumps({
        "format": "fydpad-texture-model", "kind": "friction", "format_version": 1,
        "mu": [0.5, 0.6, 0.7], "dx_mm": 0.05, "x0_mm": 0.0}))
    return path


def _view(tmp_path: Path, **render):
    """The web view of a station that was given ``render`` (no loops run: the control
    record and its writer are what the staircase and the stimuli change)."""
    from fydpad.config import StationConfig
    from fydpad.station.render import RenderSpec
    from fydpad.station.station import Station, StationOptions
    from fydpad.web.server import WebView

    station = Station(None, None, None, StationOptions(render=RenderSpec(**render)))
    return WebView(station, StationConfig(), None, tmp_path / "results", None)


def test_staircase_applies_b_to_the_friction_model_it_renders(tmp_path: Path):
    friction = str(_friction_file(tmp_path / "friction.json"))
    grating = experiment_stimuli(None, tmp_path)[0].texture
    # --texture is the friction model: slot 0.
    view = _view(tmp_path, motors="sim", texture=friction, textures=(grating,))
    view._apply_b(350.0)
    c = view.station.control_values()
    assert (c["texture_index"], c["friction_b_v"], c["vibration_enabled"]) == (0, 350, 1)
    # A grating as --texture, the friction model among the loaded ones: that one.
    view = _view(tmp_path, motors="sim", texture=grating, textures=(grating, friction))
    assert view.friction_model == friction
    view._apply_b(420.0)
    c = view.station.control_values()
    assert (c["texture_index"], c["friction_b_v"]) == (2, 420)


@pytest.mark.parametrize("render, reason", [
    ({"motors": "none"}, "drives no motors"),
    ({"motors": "sim"}, "renders none (--texture: none)"),
    ({"motors": "sim", "texture": "GRATING"}, "renders none (--texture: grating:"),
])
def test_staircase_without_a_friction_model_says_why_in_one_line(tmp_path: Path, render,
                                                                  reason):
    grating = experiment_stimuli(None, tmp_path)[0].texture
    render = {k: grating if v == "GRATING" else v for k, v in render.items()}
    view = _view(tmp_path, **render)
    assert view.friction_slot is None
    assert reason in view.friction_model and "\n" not in view.friction_model
    before = view.station.control_values()
    with pytest.raises(ExperimentError, match=r"friction:MODEL\.json"):
        StaircaseSession.open(tmp_path, "P9", present=view._apply_b)
    assert view.station.control_values() == before  # nothing changed


def test_a_stimulus_with_the_stations_own_texture_renders_slot_0(tmp_path: Path):
    from fydpad.web.experiment import Stimulus

    grating = experiment_stimuli(None, tmp_path)
    own, other = grating[0].texture, grating[1].texture
    view = _view(tmp_path, motors="sim", texture=own, textures=(own, other))
    present = view.stimulus
    for stim, slot in ((Stimulus("A", 0.5, 3.9, "", own), 0),
                       (Stimulus("B", 0.6, 2.15, "", other), 2),
                       (Stimulus("C", 0.7, 0.0, "", "lpc:not-loaded.json"), -1)):
        present(stim)
        c = view.station.control_values()
        assert (c["texture_index"], c["stiffness_n_per_mm"]) == (slot, stim.stiffness_n_per_mm)
        assert present.rendered(stim) == (slot >= 0)
    present(None)
    assert view.station.control_values()["texture_index"] == -1


def test_grating_models_are_rewritten_whole_when_their_content_differs(tmp_path: Path):
    import os

    from fydpad.texture.families import load_family

    first = experiment_stimuli(None, tmp_path)
    path = Path(first[0].texture.partition(":")[2])
    good = path.read_text()
    inode = os.stat(path).st_ino
    experiment_stimuli(None, tmp_path)
    assert os.stat(path).st_ino == inode  # the same content: left alone
    path.write_text(good[: len(good) // 2])  # a torn write of an earlier run
    again = experiment_stimuli(None, tmp_path)
    assert [s.texture for s in again] == [s.texture for s in first]
    assert path.read_text() == good
    load_family(again[0].texture)  # a whole model again
    assert not [p for p in path.parent.iterdir() if p.suffix == ".tmp"]  # no leftovers
