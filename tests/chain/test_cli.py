"""`fydpad chain identify|check` and `fydpad run --compensate`, in process."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fydpad.cli import main


def test_identify_then_check(tmp_path, capsys):
    tf = tmp_path / "tf.npz"
    rc = main(["chain", "identify", "--out", str(tf), "--plot", str(tmp_path / "tf.png"),
               "--stiffness", "0.5,0.9", "--seconds", "5", "--nperseg", "256"])
    assert rc == 0
    assert (tmp_path / "tf.png").stat().st_size > 10_000
    err = capsys.readouterr().err
    assert "k 0.5 N/mm" in err and "force 0.30" in err
    from fydpad.chain.tf_file import load_tf_set

    tfs = load_tf_set(tf, 1000.0, "vibration")
    assert [e.stiffness_n_per_mm for e in tfs.entries] == [0.5, 0.9]
    assert tfs.provenance["motors"] == "sim" and tfs.excitation["seconds"] == 5.0
    rc = main(["chain", "check", str(tf), "--stiffness", "0.9", "--seconds", "5",
               "--plot", str(tmp_path / "check.png"), "--json", str(tmp_path / "c.json")])
    assert rc == 0
    assert (tmp_path / "check.png").stat().st_size > 10_000
    figures = json.loads((tmp_path / "c.json").read_text())
    out = capsys.readouterr().out.strip()
    # A sentence, not JSON: the figures rounded as a person reads them.
    assert out.startswith("At k = 0.9 N/mm, over ") and out.endswith(".")
    assert "{" not in out and len(out.splitlines()) == 1
    assert f"within {figures['compensated_max_error_db']:.1f} dB of the target" in out


def test_check_plot_is_clipped_to_the_band(tmp_path):
    """The target falls by many decades outside the compared band: the log axis shows the
    band's levels, a decade of room below, not the decades outside it."""
    from fydpad.chain.check import CheckResult
    from fydpad.chain.plots import plot_check

    f = np.linspace(0, 500, 501)
    compared = (f >= 100) & (f <= 300)
    target = np.where(compared, 1e-2, 1e-13)
    res = CheckResult(f, target, target * 2, target * 1.1, None, compared, 200.0,
                      {"stiffness_n_per_mm": 0.9, "compensated_max_error_db": 0.4,
                       "uncompensated_error_at_resonance_db": 3.0})
    import matplotlib.pyplot as plt

    captured = {}
    real_savefig = plt.Figure.savefig

    def keep(fig, *a, **k):
        captured["ylim"] = fig.axes[0].get_ylim()
        return real_savefig(fig, *a, **k)

    plt.Figure.savefig = keep
    try:
        plot_check(tmp_path / "c.png", res)
    finally:
        plt.Figure.savefig = real_savefig
    low, high = captured["ylim"]
    assert low == pytest.approx(1e-3) and high == pytest.approx(4e-2)


@pytest.mark.parametrize("argv, message", [
    (["--band", "10,600"], "HI must stay below 450 Hz"),
    (["--band", "x"], "--band 'x': expected numbers"),
    (["--accel", "bogus"], "accelerometer 'bogus'"),
    (["--seconds", "1"], "too short for Welch averaging"),
])
def test_bad_options_one_line(tmp_path, capsys, argv, message):
    rc = main(["chain", "identify", "--out", str(tmp_path / "t.npz"), "--stiffness", "0.6",
               *argv])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "Traceback" not in err and len(err.splitlines()) == 1


def test_run_compensate_refuses_another_chain(tmp_path, capsys):
    from fydpad.chain.tf_file import save_tf_set
    from tests.chain.test_tf_file import make_set

    p = save_tf_set(make_set(48000.0, "audio"), tmp_path / "audio.npz")
    rc = main(["run", "--synthetic", "--duration", "0.1", "--motors", "sim",
               "--compensate", str(p)])
    assert rc == 2
    assert "identified on channel 'audio' at 48000 Hz" in capsys.readouterr().err


def test_drive_chain_compensates_with_the_nearest_stiffness(tmp_path):
    # The render chain the station's 1 kHz process drives, with --compensate.
    from fydpad.chain.tf_file import save_tf_set
    from fydpad.config import StationConfig
    from fydpad.station.chains import DriveChain
    from fydpad.station.render import RenderSpec
    from tests.chain.test_tf_file import make_set

    p = save_tf_set(make_set(), tmp_path / "tf.npz")
    chain = DriveChain(RenderSpec(motors="sim", config=StationConfig(), compensate=str(p)))
    try:
        for _ in range(5):
            chain.tick(0.0, False, math.nan, math.nan, 0.0, 0.0, 1.0, 0.8)
        assert chain.stats()["tf_stiffness_n_per_mm"] == 0.8
        for _ in range(5):
            chain.tick(0.0, False, math.nan, math.nan, 0.0, 0.0, 1.0, 0.5)
        st = chain.stats()
        # 0.45 (the softest, at start) -> 0.8 -> 0.45
        assert st["tf_stiffness_n_per_mm"] == 0.45 and st["tf_switches"] == 2
        assert np.isfinite(chain.compensator.tick(1.0))
    finally:
        chain.safe_stop()
