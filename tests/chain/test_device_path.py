"""``fydpad chain identify --motors qb --accel serial:PORT --sensors serial:PORT``: the
device path end to end, over three pseudo-terminals.

What is emulated (``tests/chain/device_emulation.py``, in a process of its own): the QB
board (the real packet protocol, read and written by the real ``QbMotors``) driving the
simulated fabric and motor plant on the wall clock; the fabric accelerometer (the line
protocol of docs/accel_protocol.md, read by the real ``SerialAccelerometer``) latching
that plant's acceleration on its own clock; the sensor board's load cell (read by the
real ``SerialBoard`` in the session's load-cell thread). Nothing else is emulated: the
command, its pacing, the clock alignment and the estimate are the device path's own.
"""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from fydpad.cli import main
from fydpad.motors import qb_protocol as qp
from fydpad.motors.sim import characterise_plant
from fydpad.softness import save_table
from tests.chain.device_emulation import FORCE_N, EmulatedDevice

SECONDS = 4.2  # Welch's minimum at nperseg 512 is 4.096 s
STIFFNESS = 0.6
#: |TF| of the device path against the plant's own response where coherent, dB.
MAG_TOL_DB = 2.0
#: The band compared, Hz. Above ~300 Hz the sampled TF depends on where the
#: accelerometer's samples fall between the command's edges (the plant's response to the
#: held command above Nyquist aliases back, and neither emulated part has an anti-alias
#: filter): the reference samples just before each edge, the device path at phases the
#: delivery jitter spreads, so the images cancel differently. Measured: +0.7 to +3.2 dB
#: at 350-440 Hz in 4 of 4 runs, systematic and growing toward Nyquist; within +-1.1 dB
#: below 330 Hz.
COMPARED_HZ = (10.0, 300.0)


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    return save_table(characterise_plant(), tmp_path_factory.mktemp("soft") / "table.csv")


@pytest.fixture()
def device(table: Path, tmp_path: Path):
    """The emulated device and a config naming the board's port."""
    dev = EmulatedDevice()
    cfg = tmp_path / "station.toml"
    # A stall timeout other than the default 0.5 s: the stall test sees it reach the reader.
    cfg.write_text(f'[qb]\nport = "{dev.qb_port}"\n[softness]\ntable = "{table}"\n'
                   "[accel]\nserial_timeout_s = 0.3\n[ir]\nserial_timeout_s = 0.3\n")
    yield dev, cfg
    dev.stop()


def left_safe(dev: EmulatedDevice) -> bool:
    """The board deactivated: ACTIVATE 0 is fire-and-forget, so give the emulator the
    moment it needs to read it."""
    deadline = time.monotonic() + 5.0
    while dev.state()["activation"] != 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    st = dev.state()
    return st["activation"] == 0 and not st["powered"]


def identify(dev: EmulatedDevice, cfg: Path, out: Path, sensors: bool = True) -> int:
    argv = ["chain", "identify", "--config", str(cfg), "--motors", "qb", "--accel",
            f"serial:{dev.accel_port}", "--stiffness", str(STIFFNESS), "--seconds",
            str(SECONDS), "--yes", "--out", str(out)]
    if sensors:
        return main([*argv, "--sensors", f"serial:{dev.board_port}"])
    with pytest.warns(UserWarning, match="no load cell"):
        return main(argv)


def plant_response(freqs_hz: np.ndarray) -> np.ndarray:
    """The emulated plant's own TF (duty -> fabric m/s^2) at the device path's working
    point: stiffness STIFFNESS, no finger on the fabric (the emulated device has none),
    by lock-in through the simulated drive on its virtual clock (no timing at all)."""
    from fydpad.chain.measure import settle
    from fydpad.chain.session import open_session
    from tests.chain.conftest import lock_in, sim_config

    s = open_session(sim_config(noise_m_s2=0.0), "sim", "sim")
    try:
        s.drive.set_stiffness(STIFFNESS, strict=True)
        settle(s.drive, 1000)
        return np.array([lock_in(s, f) for f in freqs_hz])
    finally:
        s.close()


def record_pwm_sends(monkeypatch) -> list[float]:
    """Monotonic time of every PWM command the host sends (taken before the write, so a
    command cannot arrive before it was sent); the board's own sends are untouched."""
    from fydpad.motors.qb import QbMotors

    sent_s: list[float] = []
    send = QbMotors.set_pwm

    def timed(self, duty0: float, duty1: float) -> None:
        sent_s.append(time.monotonic())
        send(self, duty0, duty1)

    monkeypatch.setattr(QbMotors, "set_pwm", timed)
    return sent_s


def delivery_factor_db(freqs_hz: np.ndarray, sent_s: list[float], applied_s: list[float]
                       ) -> np.ndarray:
    """|E[exp(-j 2 pi f tau)]| in dB over the delivery delays tau of the PWM commands (the
    board applied a few position commands before them: pair from the end)."""
    n = len(sent_s)
    assert n >= SECONDS * 1000 and len(applied_s) >= n, (n, len(applied_s))
    tau = np.asarray(applied_s[-n:]) - np.asarray(sent_s)
    assert tau.min() >= 0.0, "an arrival before its send: the pairing is off"
    tau -= np.median(tau)
    factor = np.abs(np.exp(-2j * np.pi * np.outer(freqs_hz, tau)).mean(axis=1))
    return 20 * np.log10(factor)


class CoherenceShortfall(AssertionError):
    """The device path refused its own measurement for too little coherence."""


@pytest.mark.xfail(strict=False, raises=CoherenceShortfall, reason=(
    "on this 2-core machine shared with other jobs the device path's coherence sometimes "
    "stays below 0.9 over most of 10-450 Hz: the plant gets each command when the "
    "pseudo-terminal delivers it (0.2-20 ms after it was sent, median 1.2, sd 0.3-0.5), "
    "which the host cannot see. Share of bins above 0.9 in 7 runs: 0.02, 0.74-1.00 in the "
    "other 6 (identify needs 0.5); 4 of 6 test runs identified, 2 with a busy process "
    "beside. Only that refusal is forgiven (not strict: when the run identifies it must "
    "match the plant within MAG_TOL_DB); any other error or a wrong TF fails"))
def test_identify_over_the_board_accelerometer_and_load_cell_ptys(device, tmp_path: Path,
                                                                   capsys, monkeypatch):
    dev, cfg = device
    out = tmp_path / "tf.npz"
    sent_s = record_pwm_sends(monkeypatch)
    rc = identify(dev, cfg, out)
    err = capsys.readouterr().err
    st = dev.state()
    # The command drove the board in PWM mode through the settle and the whole excitation,
    # then left it safe (deactivated), and read the accelerometer's stream.
    assert st["set_inputs"] >= SECONDS * 1000
    assert st["control_mode"] == qp.CONTROL_PWM and left_safe(dev)
    assert b"?" in st["accel_commands"]  # the reader asked for the hello
    if rc != 0:
        last = err.strip().splitlines()[-1]
        assert rc == 2 and "too little coherence to identify" in last, err
        raise CoherenceShortfall(last)
    from fydpad.chain.tf_file import load_tf_set

    tfs = load_tf_set(out, 1000.0, "vibration")
    assert tfs.provenance["motors"] == "qb"
    assert tfs.provenance["accel"] == f"serial:{dev.accel_port}"
    e = tfs.entries[0]
    assert e.force_mean_n == pytest.approx(FORCE_N, abs=1e-3)  # the load cell's reading
    est = e.estimate
    good = np.flatnonzero(est.coherent(COMPARED_HZ))
    assert good.size >= 20, f"only {good.size} coherent bins in {COMPARED_HZ} Hz"
    idx = good[:: max(1, good.size // 20)]
    # The plant got each command when the pseudo-terminal delivered it, 0.2-20 ms
    # (median 1.2) after it was sent, and the host cannot see when (nor can it over a real
    # board's USB link): a random delay tau scales the estimate by E[exp(-j 2 pi f tau)].
    # That factor is measured here, from this run's own sends and arrivals.
    delay_db = delivery_factor_db(est.freqs_hz[idx], sent_s, dev.applied_times())
    truth = plant_response(est.freqs_hz[idx])
    mag_db = 20 * np.log10(np.abs(est.tf[idx]) / np.abs(truth)) - delay_db
    detail = np.column_stack([est.freqs_hz[idx], mag_db, delay_db]).round(2).tolist()
    assert np.max(np.abs(mag_db)) < MAG_TOL_DB, f"[f_hz, error_db, delay_db]: {detail}"


def test_the_plant_response_the_device_path_is_checked_against():
    # The reference of the test above, checked where the chain has no timing: the
    # simulated path's own identification at the same working point agrees with it.
    from fydpad.chain.identify import identify_entry
    from fydpad.chain.measure import settle
    from fydpad.chain.session import open_session
    from tests.chain.conftest import BAND_HZ, sim_config

    s = open_session(sim_config(), "sim", "sim")
    s.hold = lambda k, force_n: (s.drive.set_stiffness(k, strict=True),
                                 settle(s.drive, 1000), 0.0)[2]  # no finger, as the device
    try:
        est = identify_entry(s, STIFFNESS, SECONDS, BAND_HZ, seed=1, force_n=0.0).estimate
    finally:
        s.close()
    good = np.flatnonzero(est.coherent(BAND_HZ))
    assert good.size > 100
    idx = good[:: good.size // 20]
    mag_db = 20 * np.log10(np.abs(est.tf[idx]) / np.abs(plant_response(est.freqs_hz[idx])))
    assert np.max(np.abs(mag_db)) < 1.0


def stop_when(dev: EmulatedDevice, ticks: int, action) -> None:
    """In a thread: ``action`` once the board got ``ticks`` SET_INPUTS (mid-excitation)."""
    def run() -> None:
        deadline = time.monotonic() + 30
        while dev.state()["set_inputs"] < ticks and time.monotonic() < deadline:
            time.sleep(0.05)
        action()

    threading.Thread(target=run, daemon=True).start()


def test_accelerometer_that_stalls_mid_run_is_one_line(device, tmp_path: Path, capsys):
    dev, cfg = device
    stop_when(dev, 1200, dev.pause_accel)  # the part stops streaming; the cable stays
    assert identify(dev, cfg, tmp_path / "tf.npz", sensors=False) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    # [accel] serial_timeout_s = 0.3 of the config reached the serial reader
    assert err.startswith("fydpad chain: error:")
    assert f"{dev.accel_port}: no valid samples from the accelerometer for 0.3 s" in err
    assert left_safe(dev)
    assert not (tmp_path / "tf.npz").exists()


def test_load_cell_that_stops_mid_run_is_one_line(device, tmp_path: Path, capsys):
    dev, cfg = device
    # The emulated QB board shares this loaded 2-core machine: its 4 ms per-tick deadline
    # measures the load, not the load cell (under load it missed 4 replies in a row
    # before the sensor board's stall): 50 ms here, as in tests/motors/test_qb.py.
    cfg.write_text(cfg.read_text().replace("[qb]\n", "[qb]\ntick_timeout_s = 0.05\n", 1))
    stop_when(dev, 1200, dev.pause_board)  # the sensor board hangs mid-excitation
    assert identify(dev, cfg, tmp_path / "tf.npz") == 2
    err = capsys.readouterr().err.strip()
    last = err.splitlines()[-1]
    assert re.match(rf"fydpad chain: error: load cell on {re.escape(dev.board_port)}: ", last), err
    assert left_safe(dev)
    assert not (tmp_path / "tf.npz").exists()
