"""Per-tick cost of the 1 kHz motor path: ``MotorDrive.tick`` (host position loop +
eq. 3) on the simulated plant, and on the QB board protocol over a pseudo-terminal
against the emulator (pipelined and request-reply reads).

    python benchmarks/bench_motors.py [--ticks N]

Wall time per tick, p50/p99 in microseconds. The pty figures include the emulator
thread (and the simulated plant it runs) competing for the same two cores, so they
bound the host's own cost from above; a real USB link adds its latency (see
docs/motors.md), which pipelining takes off the tick.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from fydpad.motors.drive import MotorDrive
from fydpad.motors.qb import QbBoardConfig, QbMotors
from fydpad.motors.qb_emulator import QbEmulator
from fydpad.motors.sim import SimMotors


def measure(drive: MotorDrive, ticks: int) -> np.ndarray:
    drive.start()
    drive.set_theta_rad(0.6)
    out = np.empty(ticks)
    for i in range(ticks):
        t0 = time.perf_counter()
        drive.tick(0.1 * np.sin(i * 0.2))
        out[i] = time.perf_counter() - t0
    drive.safe_stop()
    return out * 1e6


def report(name: str, us: np.ndarray) -> None:
    print(f"{name:32s} p50 {np.percentile(us, 50):7.1f} us   p99 {np.percentile(us, 99):7.1f} us"
          f"   max {us.max():8.1f} us")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ticks", type=int, default=5000)
    a = ap.parse_args()
    report("sim plant (drive.tick)", measure(MotorDrive(SimMotors()), a.ticks))
    for pipelined in (True, False):
        with QbEmulator() as emu:
            m = QbMotors(QbBoardConfig(port=emu.port, pipelined=pipelined))
            try:
                us = measure(MotorDrive(m), a.ticks)
            finally:
                m.close()
            report(f"qb over pty ({'pipelined' if pipelined else 'request-reply'})", us)


if __name__ == "__main__":
    main()
