"""The device the device-path tests drive: the QB board, the fabric accelerometer and the
sensor board, emulated on pseudo-terminals in a process of their own.

Why a process of its own: in the test's process the emulators' threads queue for the
GIL behind the command's paced 1 kHz loop (and it behind them), so a packet was applied
and a sample taken up to several ms late: under load the emulation, not the device
path, set the coherence (median 0.3-0.8 over 10-450 Hz). A real board and a real
accelerometer do not wait for the host's interpreter.

What is emulated, and how a real device behaves:

- The fabric and motor plant runs on the wall clock, in steps of ``PLANT_DT_S`` (0.1
  ms: the plant's own integration step), holding the last duty until a packet sets the
  next, as a motor driver does: the plant gets the commanded excitation with the host
  loop's real timing.
- The accelerometer samples on its own clock: sample k is the fabric's acceleration at
  the device time of sample k (the plant's log at that instant), whenever the emulator
  thread gets to send it, as a MEMS part latches a sample into its FIFO on time however
  late the microcontroller reads it.
- The sensor board streams a constant load (``FORCE_N``) at 100 Hz.
"""

from __future__ import annotations

import multiprocessing as mp
import threading
import time

from fydpad.accel.emulator import AccelEmulator
from fydpad.accel.serial import G_M_S2
from fydpad.motors.qb_emulator import QbEmulator
from fydpad.motors.qb_protocol import CMD_SET_INPUTS
from fydpad.motors.sim import FabricMotorPlant, PlantConfig
from vision.board_emulator import BoardEmulator
from vision.config import ForceConfig

#: The plant's wall-clock step: its integration step (1 ms ticks of 10 sub-steps).
PLANT_DT_S = 1e-4
#: The load the emulated sensor board's load cell reads.
FORCE_N = 0.3
#: The longest session a device serves, s (the plant's acceleration log is preallocated).
MAX_SESSION_S = 120.0


class WallClockPlant:
    """The simulated plant advanced to the wall clock whenever it is touched (a packet's
    new duty, after holding the old one up to now; an encoder read; an accelerometer
    sample). One lock: the emulators' threads share it."""

    def __init__(self) -> None:
        p = FabricMotorPlant(PlantConfig(dt_s=PLANT_DT_S, substeps=1))
        p.enable_accel_log(int(MAX_SESSION_S / PLANT_DT_S))
        object.__setattr__(self, "_p", p)
        object.__setattr__(self, "_lock", threading.RLock())
        object.__setattr__(self, "_t0", time.monotonic())
        object.__setattr__(self, "_n", 0)
        #: Monotonic time each duty was applied (a packet's arrival), for the tests that
        #: measure the emulation's own delivery delay.
        object.__setattr__(self, "applied_t", [])

    def __getattr__(self, name: str):
        return getattr(self._p, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._p, name, value)

    def _advance(self, t: float) -> None:
        n = int((t - self._t0) / PLANT_DT_S)
        if n > self._n:
            self._p.step(n - self._n)
            object.__setattr__(self, "_n", n)

    def set_duty(self, d0: float, d1: float) -> None:
        with self._lock:
            now = time.monotonic()
            self._advance(now)
            self._p.set_duty(d0, d1)
            self.applied_t.append(now)

    def step(self, n: int = 1) -> None:
        """The QB emulator's tick: the plant runs on the wall clock, not per packet."""
        with self._lock:
            self._advance(time.monotonic())

    def encoder_rad(self, i: int) -> float:
        with self._lock:
            self._advance(time.monotonic())
            return self._p.encoder_rad(i)

    def accel_at(self, t: float) -> float:
        """The fabric's acceleration at monotonic time ``t`` (not in the future)."""
        with self._lock:
            self._advance(min(t, time.monotonic()))
            n = min(round((t - self._t0) / PLANT_DT_S), self._n)
            log = self._p._log  # the plant's preallocated (t_s, accel) per step; no copy
            return float(log[n - 1, 1]) if n > 0 else 0.0


def pressed(k: int) -> tuple[tuple[int, int, int], int]:
    """The sensor board's line k: IR at rest, the load cell at FORCE_N."""
    return (268, 268, 268), round(FORCE_N / ForceConfig().gain_n_per_count)


def _serve(conn) -> None:
    plant = WallClockPlant()
    qb = QbEmulator(plant=plant).start()  # type: ignore[arg-type]
    acc = AccelEmulator(clocked=True)
    acc.signal_fn = lambda k: (plant.accel_at(acc.sample_time_s(k)), 0.0, G_M_S2)
    acc.start()
    board = BoardEmulator(pressed, rate_hz=100).start()
    conn.send((qb.port, acc.port, board.port))
    while True:
        cmd = conn.recv()
        if cmd == "state":
            conn.send({"set_inputs": qb.received.count(CMD_SET_INPUTS),
                       "control_mode": qb.control_mode, "activation": qb.activation,
                       "powered": plant.powered, "accel_commands": list(acc.commands)})
        elif cmd == "applied-times":
            conn.send(list(plant.applied_t))
        elif cmd == "pause-accel":
            acc.pause()
            conn.send(None)
        elif cmd == "pause-board":
            board.pause()
            conn.send(None)
        elif cmd == "stop":
            for emu in (board, acc, qb):
                emu.stop()
            conn.send(None)
            return


class EmulatedDevice:
    """The device in its own process: ``qb_port``, ``accel_port``, ``board_port``;
    ``state()`` (what the board was sent and is doing), ``pause_accel()``,
    ``pause_board()``, ``stop()``. Safe to call from several threads."""

    def __init__(self) -> None:
        ctx = mp.get_context("fork")  # fast: the child has the modules imported already
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(child,), name="fydpad-device",
                                 daemon=True)
        self._proc.start()
        self._lock = threading.Lock()
        if not self._conn.poll(30.0):
            self._proc.kill()
            raise RuntimeError("the emulated device did not start")
        self.qb_port, self.accel_port, self.board_port = self._conn.recv()

    def _call(self, cmd: str):
        with self._lock:
            self._conn.send(cmd)
            return self._conn.recv()

    def state(self) -> dict:
        return self._call("state")

    def applied_times(self) -> list[float]:
        """Monotonic time of every duty the board applied (one per SET_INPUTS packet)."""
        return self._call("applied-times")

    def pause_accel(self) -> None:
        self._call("pause-accel")

    def pause_board(self) -> None:
        self._call("pause-board")

    def stop(self) -> None:
        if self._proc.is_alive():
            try:
                self._call("stop")
            except (EOFError, OSError):
                pass
            self._proc.join(timeout=5.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join()
