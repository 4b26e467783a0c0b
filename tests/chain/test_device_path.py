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
from fydpad.motors.drive import characterise_plant
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
#: delivery jitter spreads, so the images cancel differently. Measured (delivery factor
#: applied): +0.0 to +3.6 dB at 400-445 Hz in 3 runs, mostly positive and growing toward
#: Nyquist (-0.7 to +1.0 at 290-390 Hz); within +-0.8 dB below 300 Hz.
COMPARED_HZ = (10.0, 300.0)


#: The board's host here is this test's process, not paced and not real-time, on a loaded
#: 2-core machine: a stall past the watchdog's 20 ms would stop the board, and replies
#: late past 10 ticks would fail the read; a set-up reply (ping, activate) may be late
#: past the 0.1 s default deadline, so it gets a 10 s one, a hang guard. All three are
#: tested where they are the subject (tests/motors); here they would measure the
#: machine's load, not the chain.
QB_ON_A_LOADED_MACHINE = "watchdog_cs = 0\nmax_missed_replies = 1000\ntimeout_s = 10.0\n"


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    return save_table(characterise_plant(), tmp_path_factory.mktemp("soft") / "table.csv")


@pytest.fixture()
def device(table: Path, tmp_path: Path):
    """The emulated device and a config naming the board's port."""
    dev = EmulatedDevice()
    cfg = tmp_path / "station.toml"
    # The serial parts' timeouts (the accelerometer's hello wait too) are hang guards here:
    # the emulator's process may be starved for a while on a loaded machine. The stall
    # tests set a short one for the part that stalls (with_stall_timeout).
    cfg.write_text(f'[qb]\n{QB_ON_A_LOADED_MACHINE}port = "{dev.qb_port}"\n'
                   f'[softness]\ntable = "{table}"\n'
                   f"[accel]\nserial_timeout_s = {HANG_GUARD_S}\n"
                   f"[ir]\nserial_timeout_s = {HANG_GUARD_S}\n")
    yield dev, cfg
    dev.stop()


HANG_GUARD_S = 10.0


def with_stall_timeout(cfg: Path, section: str) -> None:
    """0.3 s for ``section``'s serial part, other than the default 0.5 s: the stall test
    sees it reach the reader."""
    text = cfg.read_text()
    head, _, tail = text.partition(f"[{section}]\nserial_timeout_s = {HANG_GUARD_S}\n")
    cfg.write_text(f"{head}[{section}]\nserial_timeout_s = 0.3\n{tail}")


def left_safe(dev: EmulatedDevice) -> bool:
    """The board deactivated: ACTIVATE 0 is fire-and-forget, so give the emulator the
    moment it needs to read it."""
    deadline = time.monotonic() + 60.0  # a hang guard: the emulator may be far behind
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


def record_input_sends(monkeypatch) -> list[float]:
    """Monotonic time of every SET_INPUTS the host writes (the PWM commands and the
    deactivation's zero), taken before the write so a command cannot arrive before it
    was sent: one per duty the emulated board applies."""
    from fydpad.motors.qb import QbMotors

    sent_s: list[float] = []
    send = QbMotors._send

    def timed(self, cmd: int, payload: bytes = b"") -> None:
        if cmd in (qp.CMD_SET_INPUTS, qp.CMD_SET_INPUTS_ACK):
            sent_s.append(time.monotonic())
        send(self, cmd, payload)

    monkeypatch.setattr(QbMotors, "_send", timed)
    return sent_s


def delivery_delays_s(sent_s: list[float], applied_s: list[float]) -> np.ndarray:
    """Each SET_INPUTS's delay from its send to the board applying it (paired one to one)."""
    assert len(applied_s) == len(sent_s) >= SECONDS * 1000, (len(sent_s), len(applied_s))
    tau = np.asarray(applied_s) - np.asarray(sent_s)
    assert tau.min() >= 0.0, "an arrival before its send: the pairing is off"
    return tau


def delivery_factor_db(freqs_hz: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
    """|E[exp(-j 2 pi f tau)]| in dB over the delivery delays tau."""
    tau = tau_s - np.median(tau_s)
    factor = np.abs(np.exp(-2j * np.pi * np.outer(freqs_hz, tau)).mean(axis=1))
    return 20 * np.log10(factor)


class CoherenceShortfall(AssertionError):
    """The device path refused its own measurement for too little coherence."""


# The plant gets each command when the pseudo-terminal delivers it (median 0.14-0.18 ms
# after it was sent, p99 0.4-0.8, up to 2.8-4.8 ms), which the host cannot see. Share of
# bins above 0.9 in 7 runs: 0.02, and 0.74-1.00 in the other 6 (identify needs 0.5). Only
# that refusal is forgiven (not strict: when the run identifies it must match the plant
# within MAG_TOL_DB); any other error or a wrong TF fails.
@pytest.mark.xfail(strict=False, raises=CoherenceShortfall, reason=(
    "coherence < 0.9 over most of 10-450 Hz in 3 of 10 runs on a loaded 2-core machine"))
def test_identify_over_the_board_accelerometer_and_load_cell_ptys(device, tmp_path: Path,
                                                                   capsys, monkeypatch):
    dev, cfg = device
    out = tmp_path / "tf.npz"
    sent_s = record_input_sends(monkeypatch)
    rc = identify(dev, cfg, out)
    err = capsys.readouterr().err
    # The command left the board safe (deactivated). The emulator (a process of its own)
    # applies frames in order, however far behind a loaded machine leaves it: once it has
    # applied the deactivation it has applied every duty before it.
    assert left_safe(dev)
    st = dev.state()
    # It drove the board in PWM mode through the settle and the whole excitation, and
    # read the accelerometer's stream.
    assert st["set_inputs"] >= SECONDS * 1000
    assert st["control_mode"] == qp.CONTROL_PWM
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
    # The plant got each command when the pseudo-terminal delivered it, 0.1-5 ms
    # (median 0.15) after it was sent, and the host cannot see when (nor can it over a real
    # board's USB link): a random delay tau scales the estimate by E[exp(-j 2 pi f tau)].
    # That factor is measured here, from this run's own sends and arrivals.
    tau_s = delivery_delays_s(sent_s, dev.applied_times())
    delay_db = delivery_factor_db(est.freqs_hz[idx], tau_s)
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
    with_stall_timeout(cfg, "accel")
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
    with_stall_timeout(cfg, "ir")
    # Late replies of the emulated board are reused (QB_ON_A_LOADED_MACHINE): the run
    # fails on the load cell, not on the machine's load.
    stop_when(dev, 1200, dev.pause_board)  # the sensor board hangs mid-excitation
    assert identify(dev, cfg, tmp_path / "tf.npz") == 2
    err = capsys.readouterr().err.strip()
    last = err.splitlines()[-1]
    assert re.match(rf"fydpad chain: error: load cell on {re.escape(dev.board_port)}: ", last), err
    assert left_safe(dev)
    assert not (tmp_path / "tf.npz").exists()
