"""Open the chain a command drives: the motor drive, the fabric accelerometer, the clock
they share, the pacing and the load cell (simulated plant or the real device)."""

from __future__ import annotations

import math
import threading
import time
import warnings
from contextlib import ExitStack
from dataclasses import dataclass, replace

import numpy as np

from fydpad.accel import open_accelerometer
from fydpad.accel.base import AccelError
from fydpad.chain import ChainError
from fydpad.chain.measure import press_to_force, settle
from fydpad.motors.drive import build_drive
from fydpad.pacing import LoopTimer

#: Ticks allowed for a new stiffness position to settle before measuring.
SETTLE_S = 1.0
#: The simulated load cell's noise, N rms.
SIM_FORCE_NOISE_N = 0.01


@dataclass
class ChainSession:
    """A started drive with its accelerometer; ``close`` leaves it safe."""

    drive: object
    accel: object
    accel_spec: str
    motors: str
    plant: object | None
    sensors: object | None
    rng: np.random.Generator

    @property
    def rate_hz(self) -> float:
        return self.drive.config.rate_hz

    def clock(self) -> float:
        """End-of-tick time: the plant's virtual clock, or the host's on the device."""
        return self.plant.t_s if self.plant is not None else time.perf_counter()

    def force(self) -> float:
        """One load-cell reading, N (NaN without a load cell; ChainError when the load
        cell failed or stopped)."""
        if self.plant is not None:
            return self.plant.force_n() + self.rng.normal(0.0, SIM_FORCE_NOISE_N)
        if self.sensors is not None:
            return self.sensors.force_n()
        return math.nan

    def hold(self, stiffness_n_per_mm: float, force_n: float) -> float:
        """Go to the stiffness setting and let it settle; on the simulated plant the
        finger presses with ``force_n`` (on the device the user does). Returns theta."""
        d = self.drive
        d.set_stiffness(stiffness_n_per_mm, strict=True)
        if self.plant is not None:
            settle(d, int(SETTLE_S * self.rate_hz))
            press_to_force(self.plant, force_n)
            settle(d, int(0.2 * self.rate_hz))
            return 0.5 * (self.plant.theta_rad[0] + self.plant.theta_rad[1])
        pace = self.pacer()
        for _ in range(int(SETTLE_S * self.rate_hz)):
            pace()
            d.tick(0.0)
        th = d.motors.read_positions_rad()
        return 0.5 * (th[0] + th[1])

    def pacer(self):
        """The per-tick wait: none on the simulated plant (virtual clock), a LoopTimer
        at the render rate on the device."""
        if self.plant is not None:
            return None
        timer = LoopTimer(self.rate_hz, "chain")
        timer.start()
        return timer.wait

    def close(self) -> None:
        """Motors safe and their port closed, the accelerometer and the load cell closed."""
        _close_drive(self.drive)
        _disconnect(self.accel)
        if self.sensors is not None:
            self.sensors.close()


def _close_drive(drive) -> None:
    """Vibration off, motors at rest and unpowered, then the board's port closed."""
    drive.safe_stop()
    close = getattr(drive.motors, "close", None)  # the QB board's port; the plant has none
    if close is not None:
        close()


def _disconnect(accel) -> None:
    try:
        accel.disconnect()
    except (AccelError, OSError):
        pass


class LoadCellThread:
    """The sensor board's load cell read in a thread of its own (its reads block for a
    board period, the 1 kHz drive must not). ``force_n()`` is the newest force, N, or a
    ChainError naming the port when the board failed or sent no force for ``max_age_s``
    (a held force it did not measure is never reported)."""

    def __init__(self, board, max_age_s: float) -> None:
        self.board = board
        self.port = board.port
        self.max_age_s = float(max_age_s)
        # (force N, monotonic time of the reading): one tuple, replaced whole, so the
        # reader never pairs a force with another reading's time.
        self._latest = (math.nan, time.monotonic())
        self.error: Exception | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="load-cell", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                _, f = self.board.read()
            except Exception as exc:  # raised to the command by the next force_n()
                self.error = exc
                return
            if f is not None:
                self._latest = (float(f.force_n), time.monotonic())

    def force_n(self) -> float:
        if self.error is not None:
            raise ChainError(f"load cell on {self.port}: {self.error}")
        force_n, t_s = self._latest
        age_s = time.monotonic() - t_s
        if age_s > self.max_age_s:
            what = "no force reading yet" if math.isnan(force_n) else "no force reading"
            raise ChainError(f"load cell on {self.port}: {what} for {age_s:.2f} s (is the "
                             "load cell connected to the sensor board?)")
        return force_n

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.board.close()


def open_session(config, motors: str = "sim", accel_spec: str | None = None,
                 sensors_spec: str | None = None, seed: int = 0) -> ChainSession:
    """Build the drive (``motors`` sim|qb through ``build_drive``), open and connect the
    accelerometer (``accel_spec``, default the config's ``[accel] device``) and, on the
    device, the load cell of the serial sensor board. ChainError names the device that
    failed; whatever was opened before it is closed again."""
    accel_spec = accel_spec or config.accel.device
    with ExitStack() as opened:  # closes what is open if a later device fails
        drive = build_drive(replace(config.motors, backend=motors), config.pwm, config.qb,
                            config.softness)
        opened.callback(_close_drive, drive)
        plant = drive.motors.plant if motors == "sim" else None
        try:
            accel = open_accelerometer(accel_spec, plant, config.accel.serial_timeout_s)
        except (AccelError, ValueError, OSError) as exc:
            raise ChainError(f"accelerometer {accel_spec!r}: {exc}") from None
        opened.callback(_disconnect, accel)
        if hasattr(accel, "noise_m_s2") and plant is not None:
            accel.noise_m_s2 = config.accel.sim_noise_m_s2
        sensors = None
        if sensors_spec:
            sensors = _open_load_cell(config, sensors_spec)
            opened.callback(sensors.close)
        elif plant is None:
            warnings.warn("no load cell (--sensors): the normal force is not monitored; "
                          "hold it at the requested force yourself", stacklevel=2)
        try:
            accel.connect()
        except (AccelError, ValueError, OSError) as exc:
            raise ChainError(f"accelerometer {accel_spec!r}: {exc}") from None
        drive.start()  # MotorError names the board
        opened.pop_all()
    return ChainSession(drive, accel, accel_spec, motors, plant, sensors,
                        np.random.default_rng(seed))


def _open_load_cell(config, sensors_spec: str) -> LoadCellThread:
    """The sensor board of ``--sensors`` and its load-cell thread; ChainError naming it."""
    # lazy: vision.sensors loads OpenCV (through vision.recording); only the device's load
    # cell needs it
    from vision.sensors import SensorError, SerialBoard, parse_serial_spec

    try:
        port, baud = parse_serial_spec(sensors_spec)
    except ValueError as exc:
        raise ChainError(f"--sensors: {exc}") from None
    timeout_s = config.ir.serial_timeout_s
    try:
        board = SerialBoard(port, baud, ir_config=config.ir, force_config=config.force,
                            timeout_s=timeout_s)
    except (SensorError, ValueError, OSError) as exc:
        raise ChainError(f"--sensors: {exc}") from None
    # A reading older than the board's own silence timeout is a load cell that stopped.
    return LoadCellThread(board, max_age_s=timeout_s)
