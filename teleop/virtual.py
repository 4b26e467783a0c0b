"""The whole chain in virtual time: master pacing, link latency, slave loop, arm physics.

Same SlaveLoop, safety, prediction and arm code as the live link, with the socket
replaced by in-memory delivery after a fixed latency and the clock by a counter. The
figures are then the algorithm's and the arm's, free of the host's load, and
reproducible; the live figures (master.run_session) add the real link and scheduler.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

from teleop import protocol as P
from teleop.config import TeleopConfig
from teleop.mapping import Mapping
from teleop.master import Session, StreamLog, _position, build_report, rate_due
from teleop.slave import SlaveLoop, make_arm
from teleop.slaves import Arm
from vision.state import FingerState

_PEER = b"virtual-master"


class _MemorySocket:
    """Stands in for the ROUTER: collects what the slave sends."""

    def __init__(self) -> None:
        self.sent: list[bytes] = []
        self.sock = self

    def send_multipart(self, frames: list[bytes], flags: int = 0) -> None:
        self.sent.append(frames[1])


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _pass(loop: SlaveLoop, mem: _MemorySocket, clock: _Clock, states: Sequence[FingerState],
          preroll: FingerState, latency_s: float, seq0: int, rate_hz: float | None,
          hold_mode: bool, preroll_s: float = 0.5, tail_s: float = 0.3) -> StreamLog:
    log = StreamLog()
    period = loop.cfg.slave.period_s
    events: list[tuple[float, int, bytes]] = []  # (arrival, order, message)
    seq = seq0
    t_start = clock.t + period
    n_pre = round(preroll_s * 30.0)

    def send(fs: FingerState, t_cap: float) -> None:
        nonlocal seq
        x, y, z = _position(fs)
        msg = P.Sample(seq, t_cap, t_cap, x, y, z, fs.force_n, fs.contact, hold_mode)
        heapq.heappush(events, (t_cap + latency_s, seq, P.encode_sample(msg)))
        seq += 1
        log.sent += 1

    for k in range(n_pre):
        send(preroll, t_start + k / 30.0)
    log.t0_s = t_start + n_pre / 30.0
    log.t_s0 = states[0].t_s
    last = -math.inf
    for fs in states:
        t_due = log.t0_s + fs.t_s - log.t_s0
        log.record(fs, t_due)
        if rate_due(rate_hz, fs.t_s, last):
            send(fs, t_due)
            last = fs.t_s
    t_end = log.t0_s + states[-1].t_s - log.t_s0 + tail_s
    while clock.t < t_end:
        t_next = clock.t + period
        while events and events[0][0] <= t_next:
            t_arr, _, buf = heapq.heappop(events)
            clock.t = max(clock.t, t_arr)
            loop._on_message([_PEER, buf], clock.t)
        clock.t = t_next
        loop.tick(clock.t, period)
        for buf in mem.sent:
            log.states.append((clock.t + latency_s, P.decode_state(buf)))
        mem.sent.clear()
    log.next_seq = seq
    return log


def simulate_session(states: Sequence[FingerState], cfg: TeleopConfig | None = None, *,
                     truth: np.ndarray | None = None, baseline: bool = True,
                     latency_s: float = 0.0005, arm: Arm | None = None) -> Session:
    """run_session in virtual time (default arm: the PyBullet iiwa). Same report keys;
    ``latency_ms`` is the configured ``latency_s``."""
    cfg = cfg or TeleopConfig()
    arm = arm or make_arm(cfg)
    mem = _MemorySocket()
    clock = _Clock()
    arm.start(Mapping(cfg.mapping).to_robot(np.zeros(3)))
    try:
        loop = SlaveLoop(arm, mem, cfg, clock=clock)  # type: ignore[arg-type]
        pre = next((s for s in states if s.contact), states[0])
        main = _pass(loop, mem, clock, states, pre, latency_s, 1, None, False)
        base = None
        if baseline:
            for _ in range(int(0.5 / cfg.slave.period_s)):  # idle between passes, as live
                clock.t += cfg.slave.period_s
                loop.tick(clock.t, cfg.slave.period_s)
            mem.sent.clear()
            base = _pass(loop, mem, clock, states, pre, latency_s,
                         main.next_seq, cfg.baseline_rate_hz, True)
    finally:
        arm.close()
    return Session(build_report(main, base, truth), main, base)
