"""Opening the chain's devices (``fydpad.chain.session``): a device that cannot be opened
is a one-line error naming it, and what was opened before it is closed again; the load
cell of the sensor board, read in its thread, is an error naming its port when it fails
or stops sending a force, never a held force it did not measure.

The devices are the emulators on pseudo-terminals (the QB board, the accelerometer, the
sensor board), read by the real backends. Whether a port is still open is read from this
process's file descriptors (/proc/self/fd): the emulator holds one on its own pty end.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import pytest

from fydpad.accel.emulator import AccelEmulator
from fydpad.chain import ChainError
from fydpad.chain.session import LoadCellThread
from fydpad.cli import main
from fydpad.motors.drive import characterise_plant
from fydpad.motors.qb_emulator import QbEmulator
from fydpad.softness import save_table
from vision.board_emulator import BoardEmulator
from vision.config import ForceConfig
from vision.sensors import SerialBoard

FORCE_N = 0.3
#: Raw counts of FORCE_N with the default load-cell calibration (offset 0).
FORCE_RAW = round(FORCE_N / ForceConfig().gain_n_per_count)


def fds_on(path: str) -> int:
    """How many of this process's file descriptors are open on ``path``."""
    n = 0
    for fd in os.listdir("/proc/self/fd"):
        try:
            n += os.readlink(f"/proc/self/fd/{fd}") == path
        except OSError:
            pass  # the listing's own descriptor, gone by now
    return n


def pressed(k: int) -> tuple[tuple[int, int, int], int]:
    return (268, 268, 268), FORCE_RAW


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    return save_table(characterise_plant(), tmp_path_factory.mktemp("soft") / "table.csv")


#: The board's host here is this test's process, not paced and not real-time, on a loaded
#: 2-core machine: a stall past the watchdog's 20 ms would stop the board, and replies
#: late past 10 ticks would fail the read. Both are tested where they are the subject
#: (tests/motors); here they would measure the machine's load, not the chain.
QB_ON_A_LOADED_MACHINE = "watchdog_cs = 0\nmax_missed_replies = 1000\n"


@pytest.fixture()
def qb(table: Path, tmp_path: Path):
    with QbEmulator() as emu:
        cfg = tmp_path / "station.toml"
        cfg.write_text(f'[qb]\n{QB_ON_A_LOADED_MACHINE}port = "{emu.port}"\n'
                       f'[softness]\ntable = "{table}"\n'
                       "[accel]\nserial_timeout_s = 0.3\n[ir]\nserial_timeout_s = 0.3\n")
        yield emu, cfg


def identify(cfg: Path, accel: str, sensors: str, out: Path) -> int:
    return main(["chain", "identify", "--config", str(cfg), "--motors", "qb", "--accel",
                 accel, "--sensors", sensors, "--stiffness", "0.6", "--seconds", "4.2",
                 "--yes", "--out", str(out)])


def test_a_missing_sensor_board_is_one_line_and_closes_the_board(qb, tmp_path, capsys):
    emu, cfg = qb
    with AccelEmulator(clocked=True).start() as acc:
        held = fds_on(emu.port), fds_on(acc.port)
        rc = identify(cfg, f"serial:{acc.port}", "serial:/dev/ttyNOPE", tmp_path / "tf.npz")
        err = capsys.readouterr().err.strip()
        assert rc == 2 and "\n" not in err, err
        assert err.startswith("fydpad chain: error: --sensors: /dev/ttyNOPE: cannot open "
                              "the sensor board"), err
        assert "accelerometer" not in err
        # The QB board's port (opened first) is closed again; the accelerometer's was
        # never opened.
        assert (fds_on(emu.port), fds_on(acc.port)) == held == (1, 1)
    assert not (tmp_path / "tf.npz").exists()


def test_a_missing_accelerometer_is_one_line_and_closes_board_and_load_cell(qb, tmp_path,
                                                                            capsys):
    emu, cfg = qb
    with BoardEmulator(pressed, rate_hz=100).start() as board:
        held = fds_on(emu.port), fds_on(board.port)
        rc = identify(cfg, "serial:/dev/ttyNOPE", f"serial:{board.port}",
                      tmp_path / "tf.npz")
        err = capsys.readouterr().err.strip()
        assert rc == 2 and "\n" not in err, err
        assert err.startswith("fydpad chain: error: accelerometer 'serial:/dev/ttyNOPE': "
                              "/dev/ttyNOPE: cannot open the accelerometer"), err
        # The QB board's and the sensor board's ports are closed, the load-cell thread
        # is gone.
        assert (fds_on(emu.port), fds_on(board.port)) == held == (1, 1)
        assert not any(t.name == "load-cell" for t in __import__("threading").enumerate())


def wait_for_error(cell: LoadCellThread, limit_s: float = 10.0) -> ChainError:
    """The first ChainError of ``force_n`` (bounded, so a broken reader cannot hang)."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        try:
            cell.force_n()
        except ChainError as exc:
            return exc
        time.sleep(0.01)
    raise AssertionError(f"the load cell reported no fault in {limit_s} s")


def first_force(cell: LoadCellThread, limit_s: float = 5.0) -> float:
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        f = cell.force_n()
        if not math.isnan(f):
            return f
        time.sleep(0.01)
    raise AssertionError("no force from the load cell")


def test_a_load_cell_that_stops_is_an_error_naming_the_port():
    with BoardEmulator(pressed, rate_hz=100).start() as board:
        cell = LoadCellThread(SerialBoard(board.port, timeout_s=0.3), max_age_s=0.3)
        try:
            assert first_force(cell) == pytest.approx(FORCE_N, abs=1e-3)
            board.pause()  # the board hangs, the cable stays
            err = str(wait_for_error(cell))
        finally:
            cell.close()
    assert err.startswith(f"load cell on {board.port}:"), err


def test_a_load_cell_that_stops_sending_a_force_is_not_held():
    # The board keeps streaming IR, its force field empty from sample 20 on (the load
    # cell unplugged from the board): the last force must not be reported on and on.
    def cell_lost(k: int):
        return (268, 268, 268), (FORCE_RAW if k < 20 else None)

    with BoardEmulator(cell_lost, rate_hz=100).start() as board:
        cell = LoadCellThread(SerialBoard(board.port, timeout_s=0.3), max_age_s=0.3)
        try:
            assert first_force(cell) == pytest.approx(FORCE_N, abs=1e-3)
            err = str(wait_for_error(cell))
        finally:
            cell.close()
    assert err.startswith(f"load cell on {board.port}: no force reading for"), err
    assert board.k > 20  # the board itself went on streaming


def test_a_run_with_reads_missing_their_force_is_refused():
    from fydpad.chain.measure import check_force

    with pytest.raises(ChainError, match=r"no force for 2 of 5 reads"):
        check_force(np.array([0.3, 0.3, math.nan, 0.3, math.nan]), 0.3, 0.1, "k 0.6")
    assert all(math.isnan(v) for v in check_force(np.full(4, math.nan), 0.3, 0.1, "k"))
