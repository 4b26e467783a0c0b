"""``fydpad chain identify --motors qb --accel serial:PORT``: the device path end to end,
over two pseudo-terminals.

What is emulated: the QB board (:class:`fydpad.motors.qb_emulator.QbEmulator`, the real
packet protocol, read and written by the real ``QbMotors``) drives the simulated fabric
and motor plant; the fabric accelerometer (:class:`fydpad.accel.emulator.AccelEmulator`,
the line protocol of docs/accel_protocol.md, read by the real ``SerialAccelerometer``)
samples that same plant on its own clock. The plant runs on the wall clock (the duty a
packet sets is held until the next, as a motor driver does), so the accelerometer sees the
fabric move as the command's paced 1 kHz loop drives it, through both serial links.
Nothing else is emulated: the command, its pacing, the clock alignment and the estimate
are the device path's own. There is no load cell (--sensors): the force is not monitored.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from fydpad.accel.emulator import AccelEmulator
from fydpad.accel.serial import G_M_S2
from fydpad.cli import main
from fydpad.motors import qb_protocol as qp
from fydpad.motors.qb_emulator import QbEmulator
from fydpad.motors.sim import FabricMotorPlant, characterise_plant
from fydpad.softness import save_table

SECONDS = 4.2  # Welch's minimum at nperseg 512 is 4.096 s


class WallClockPlant:
    """The simulated plant advanced to the wall clock whenever it is touched: by a
    packet's new duty (after holding the old one up to now) or by an accelerometer
    sample. One lock: the two emulators' threads share it."""

    def __init__(self, plant: FabricMotorPlant) -> None:
        object.__setattr__(self, "_p", plant)
        object.__setattr__(self, "_lock", threading.RLock())
        object.__setattr__(self, "_t0", time.monotonic())
        object.__setattr__(self, "_n", 0)

    def __getattr__(self, name: str):
        return getattr(self._p, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._p, name, value)

    def _advance(self) -> None:
        n = int((time.monotonic() - self._t0) / self._p.config.dt_s)
        if n > self._n:
            self._p.step(n - self._n)
            object.__setattr__(self, "_n", n)

    def set_duty(self, d0: float, d1: float) -> None:
        with self._lock:
            self._advance()
            self._p.set_duty(d0, d1)

    def step(self, n: int = 1) -> None:
        with self._lock:
            self._advance()

    def fabric_accel(self, k: int) -> tuple[float, float, float]:
        with self._lock:
            self._advance()
            return self._p.fabric_accel_m_s2, 0.0, G_M_S2


@pytest.fixture()
def device(tmp_path: Path):
    """The QB board and the accelerometer on ptys, and a config naming the board's port."""
    table = save_table(characterise_plant(), tmp_path / "table.csv")
    plant = WallClockPlant(FabricMotorPlant())
    qb = QbEmulator(plant=plant).start()
    acc = AccelEmulator(plant.fabric_accel, clocked=True).start()
    cfg = tmp_path / "station.toml"
    # A stall timeout other than the default 0.5 s: the stall test sees it reach the reader.
    cfg.write_text(f'[qb]\nport = "{qb.port}"\n[softness]\ntable = "{table}"\n'
                   "[accel]\nserial_timeout_s = 0.3\n")
    yield qb, acc, cfg
    acc.stop()
    qb.stop()


def left_safe(qb: QbEmulator) -> bool:
    """The board deactivated: ACTIVATE 0 is fire-and-forget, so give the emulator's thread
    the moment it needs to read it."""
    deadline = time.monotonic() + 5.0
    while qb.activation != 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    return qb.activation == 0 and not qb.plant.powered


def identify(acc, cfg: Path, out: Path) -> int:
    with pytest.warns(UserWarning, match="no load cell"):
        return main(["chain", "identify", "--config", str(cfg), "--motors", "qb", "--accel",
                     f"serial:{acc.port}", "--stiffness", "0.6", "--seconds", str(SECONDS),
                     "--yes", "--out", str(out)])


def test_identify_over_the_board_and_accelerometer_ptys(device, tmp_path: Path, capsys):
    qb, acc, cfg = device
    out = tmp_path / "tf.npz"
    rc = identify(acc, cfg, out)
    captured = capsys.readouterr()
    # The command drove the board in PWM mode through the settle and the whole excitation,
    # then left it safe (deactivated), and read the accelerometer's stream.
    ticks = qb.received.count(qp.CMD_SET_INPUTS)
    assert ticks >= SECONDS * 1000
    assert qb.control_mode == qp.CONTROL_PWM and left_safe(qb)
    assert b"?" in acc.commands  # the reader asked for the hello
    if rc == 0:
        from fydpad.chain.tf_file import load_tf_set

        tfs = load_tf_set(out, 1000.0, "vibration")
        assert tfs.provenance["motors"] == "qb"
        assert tfs.provenance["accel"] == f"serial:{acc.port}"
        assert np.isnan(tfs.entries[0].force_mean_n)  # no load cell
    else:
        # The paced loop shares this 2-core machine with other jobs: its tick jitter can
        # cost the coherence, which the command then refuses, in one line, naming it.
        err = captured.err.strip().splitlines()[-1]
        assert rc == 2 and "too little coherence to identify" in err, captured.err
        pytest.xfail(f"the paced 1 kHz loop was too irregular on this machine: {err}")


def test_accelerometer_that_stalls_mid_run_is_one_line(device, tmp_path: Path, capsys):
    qb, acc, cfg = device

    def stall_in_the_excitation() -> None:
        deadline = time.monotonic() + 30
        while qb.received.count(qp.CMD_SET_INPUTS) < 1200 and time.monotonic() < deadline:
            time.sleep(0.05)
        acc.pause()  # the part stops streaming; the cable stays

    threading.Thread(target=stall_in_the_excitation, daemon=True).start()
    assert identify(acc, cfg, tmp_path / "tf.npz") == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    # [accel] serial_timeout_s = 0.3 of the config reached the serial reader
    assert err.startswith("fydpad chain: error:")
    assert f"{acc.port}: no valid samples from the accelerometer for 0.3 s" in err
    assert left_safe(qb)
    assert not (tmp_path / "tf.npz").exists()
