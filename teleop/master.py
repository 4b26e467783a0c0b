"""Master side: stream FingerState samples to a slave at their real rate, collect its state,
and build the report of docs/recording_format.md (paper IV-B, eq. 6).

    from teleop.master import run_session
    session = run_session(states, "tcp://127.0.0.1:5555", truth=truth_rows)
    print(session.report)
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import zmq

from teleop import protocol as P
from teleop.config import TeleopConfig
from teleop.link import MasterSocket, wait_readable
from teleop.realtime import realtime_scheduling
from teleop.report import (
    axes_dict,
    best_lag_s,
    latency_ms,
    mae_per_axis,
    plot_tracking,
    truth_breakdown,
)
from teleop.slave import SlaveThread
from vision.state import FingerState


@dataclass
class StreamLog:
    """What one streaming pass saw, in the master's clock."""

    t_s: list[float] = field(default_factory=list)  # capture time of every recording sample
    master_mm: list[tuple[float, float, float]] = field(default_factory=list)
    contact: list[bool] = field(default_factory=list)
    sent: int = 0
    send_failed: int = 0
    states: list[tuple[float, P.State]] = field(default_factory=list)  # (arrival, state)
    t0_s: float = 0.0  # master clock of recording time t_s0
    t_s0: float = 0.0
    next_seq: int = 1  # where a following pass continues the sequence

    def record(self, fs: FingerState, t_due_s: float) -> None:
        """One recording sample, due at ``t_due_s`` on the master's clock."""
        self.t_s.append(t_due_s)
        self.master_mm.append(_position(fs))
        self.contact.append(bool(fs.contact))

    def offset_s(self) -> float:
        """Slave clock - master clock, from the echo with the shortest round trip (NTP)."""
        best = (math.inf, 0.0)
        for t4, st in self.states:
            if st.reason != P.REASON_ACK or not math.isfinite(st.t_echo_send_s):
                continue
            t1, t2, t3 = st.t_echo_send_s, st.t_echo_recv_s, st.t_slave_s
            rtt = (t4 - t1) - (t3 - t2)
            if rtt < best[0]:
                best = (rtt, ((t2 - t1) + (t3 - t4)) / 2.0)
        return best[1]

    def latencies_s(self) -> np.ndarray:
        """One-way master -> slave latency of each acknowledged sample."""
        off = self.offset_s()
        seen: dict[int, float] = {}
        for _, st in self.states:
            if st.reason == P.REASON_ACK and st.echo_seq not in seen:
                seen[st.echo_seq] = st.t_echo_recv_s - off - st.t_echo_send_s
        return np.array(list(seen.values()))

    def slave_log(self) -> tuple[np.ndarray, np.ndarray]:
        """Slave actual positions (workspace frame) against master-clock time, sorted."""
        off = self.offset_s()
        rows = sorted({st.t_slave_s: st.actual_mm for _, st in self.states
                       if st.reason == P.REASON_TICK}.items())
        if not rows:
            return np.empty(0), np.empty((0, 3))
        t = np.array([r[0] for r in rows]) - off
        return t, np.array([r[1] for r in rows])

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (np.array(self.t_s), np.array(self.master_mm, float).reshape(-1, 3),
                np.array(self.contact, bool))


def rate_due(rate_hz: float | None, t_s: float, last_sent_t_s: float) -> bool:
    """Whether the sample at recording time ``t_s`` is sent at ``rate_hz`` (None: all)."""
    return rate_hz is None or t_s - last_sent_t_s >= 1.0 / rate_hz - 1e-6


def _position(fs: FingerState) -> tuple[float, float, float]:
    z = fs.indentation_mm if math.isfinite(fs.indentation_mm) else 0.0
    if not fs.contact:
        return (math.nan, math.nan, 0.0)
    return (fs.x_mm, fs.y_mm, z)


def stream(states: Iterable[FingerState], sock: MasterSocket, *, rate_hz: float | None = None,
           hold_mode: bool = False, preroll_s: float = 0.5, tail_s: float = 0.3,
           first_seq: int = 1, preroll_state: FingerState | None = None,
           operator_hold: Callable[[float], bool] | None = None,
           clock: Callable[[], float] = time.monotonic) -> StreamLog:
    """Send ``states`` at the times their ``t_s`` say, collecting slave states meanwhile.

    ``rate_hz`` decimates (the paper's 10 Hz master); every input sample is still logged
    as the master position to score against. ``preroll_s`` of ``preroll_state`` (default:
    the first sample) brings the arm to the start first (not scored).
    ``operator_hold(t_s)``: whether the operator holds the robot at recording time ``t_s``
    (the samples then carry the operator-hold flag).
    """
    log = StreamLog()
    seq = first_seq

    def collect_until(t_end: float) -> None:
        while True:
            while True:
                try:
                    buf = sock.sock.recv(zmq.NOBLOCK)
                except zmq.Again:
                    break
                try:
                    log.states.append((clock(), P.decode_state(buf)))
                except P.ProtocolError:
                    pass  # not ours; the slave never sends these
            if not wait_readable(sock.sock, t_end, clock):
                return

    def send(fs: FingerState, t_cap: float) -> None:
        nonlocal seq
        x, y, z = _position(fs)
        force = fs.force_n if math.isfinite(fs.force_n) else math.nan
        held = operator_hold is not None and operator_hold(fs.t_s)
        msg = P.Sample(seq, t_cap, clock(), x, y, z, force, fs.contact, hold_mode, held)
        seq += 1
        if sock.send(P.encode_sample(msg)):
            log.sent += 1
        else:
            log.send_failed += 1

    # The log grows by a few objects per sample; a full (generation 2) collection over it
    # stalled this loop for 55-175 ms every 15-20 s at 1 kHz (docs/teleop.md), and the
    # samples due meanwhile left in one burst that overflowed the send queue. A stream
    # makes no reference cycles worth collecting, so the collector waits until it ends.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        it = iter(states)
        first = next(it, None)
        if first is None:
            return log
        _stream_all(first, it, log, send, collect_until, rate_hz, preroll_s, preroll_state,
                    clock)
        collect_until(clock() + tail_s)
    finally:
        if gc_was_enabled:
            gc.enable()
    log.next_seq = seq
    return log


def _stream_all(first: FingerState, it: Iterable[FingerState], log: StreamLog,
                send: Callable[[FingerState, float], None],
                collect_until: Callable[[float], None], rate_hz: float | None,
                preroll_s: float, preroll_state: FingerState | None,
                clock: Callable[[], float]) -> None:
    period_pre = 1.0 / 30.0
    t_start = clock() + 0.05
    n_pre = round(preroll_s / period_pre)
    for k in range(n_pre):
        t_due = t_start + k * period_pre
        collect_until(t_due)
        send(preroll_state or first, t_due)
    log.t0_s = t_start + n_pre * period_pre
    log.t_s0 = first.t_s
    last_sent_t = -math.inf
    for fs in _chain(first, it):
        t_due = log.t0_s + (fs.t_s - log.t_s0)
        collect_until(t_due)
        log.record(fs, t_due)
        if rate_due(rate_hz, fs.t_s, last_sent_t):
            send(fs, t_due)
            last_sent_t = fs.t_s


def _chain(first: FingerState, rest: Iterable[FingerState]) -> Iterable[FingerState]:
    yield first
    yield from rest


def _dropped(log: StreamLog) -> int:
    """Samples the slave refused during this pass, plus those never sent or lost.

    A slave's counters are its process's: a restarted slave counts from 0 again (seen as
    ``received`` or ``dropped`` going down), so the pass is split there and each slave's
    counters are differenced on their own."""
    states = [st for _, st in log.states]
    if not states:
        return log.sent + log.send_failed
    delivered = refused = 0
    first = prev = states[0]
    for st in [*states[1:], None]:
        if st is None or st.received < prev.received or st.dropped < prev.dropped:
            delivered += prev.received - first.received + 1
            refused += prev.dropped - first.dropped
            first = st
        prev = st if st is not None else prev
    return log.send_failed + max(0, log.sent - delivered) + refused


@dataclass
class Session:
    """A finished session: the report and the logs behind it (for plots)."""

    report: dict
    main: StreamLog
    baseline: StreamLog | None

    def series(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                              tuple[np.ndarray, np.ndarray] | None]:
        """What the Fig. 11-like plot draws, time from the main pass's start (s): master
        times and positions, slave times and positions, the paper condition's slave
        (times, positions) or None."""
        t, m, _ = self.main.arrays()
        tl, sl = self.main.slave_log()
        t0 = self.main.t0_s
        base = None
        if self.baseline is not None:
            tb, sb = self.baseline.slave_log()
            base = (tb - self.baseline.t0_s, sb)
        return t - t0, m, tl - t0, sl, base

    def plot(self, path: str, title: str = "") -> None:
        """Fig. 11-like PNG: master vs slave per axis, with the paper condition if run."""
        plot_tracking(path, *self.series(), title)


def run_session(states: Sequence[FingerState], endpoint: str, cfg: TeleopConfig | None = None,
                *, truth: np.ndarray | None = None, baseline: bool = True,
                on_sample: Callable[[], None] | None = None) -> Session:
    """Stream a recording's states to the slave at ``endpoint`` and build the report.

    ``truth``: rows ``t_s, contact, x_mm, y_mm, z_mm`` on the recording's time base
    (truth.csv) for ``truth_mae_mm``. ``baseline``: a second pass under the paper's
    condition (``cfg.baseline_rate_hz`` master, slave holds each sample).
    """
    cfg = cfg or TeleopConfig()
    # Pre-roll on the first touch: the arm starts where the finger first lands.
    pre = next((s for s in states if s.contact), None)
    with realtime_scheduling(cfg.link.rt_priority), MasterSocket(endpoint, cfg.link) as sock:
        _wait_for_slave(sock, endpoint)
        main = stream(_counted(states, on_sample), sock, preroll_state=pre)
        base = None
        if baseline:
            base = stream(_counted(states, on_sample), sock, rate_hz=cfg.baseline_rate_hz,
                          hold_mode=True,
                          first_seq=main.next_seq,
                          preroll_state=pre)
    return Session(build_report(main, base, truth), main, base)


def _counted(states: Iterable[FingerState],
             on_sample: Callable[[], None] | None) -> Iterable[FingerState]:
    """``states``, calling ``on_sample`` as each is taken (a progress bar)."""
    if on_sample is None:
        yield from states
        return
    for fs in states:
        yield fs
        on_sample()


def build_report(main: StreamLog, base: StreamLog | None,
                 truth: np.ndarray | None = None) -> dict:
    """The docs/recording_format.md report from a main pass and an optional baseline pass."""
    t, m, c = main.arrays()
    tl, sl = main.slave_log()
    mae = mae_per_axis(t, m, c, tl, sl)
    rep: dict = {"mae_mm": axes_dict(mae)}
    if base is not None:
        tb, mb, cb = base.arrays()
        tlb, slb = base.slave_log()
        rep["baseline_mae_mm"] = axes_dict(mae_per_axis(tb, mb, cb, tlb, slb))
    rep["lag_ms"] = round(best_lag_s(t, m, c, tl, sl) * 1e3, 1)
    rep["latency_ms"] = latency_ms(main.latencies_s())
    rep["samples"] = int(t.size)
    rep["dropped"] = _dropped(main)
    rep["duration_s"] = round(float(t[-1] - t[0]) if t.size else 0.0, 3)
    if truth is not None:
        tt = np.asarray(truth, float)
        t_true = main.t0_s + (tt[:, 0] - main.t_s0)
        rep["truth_mae_mm"] = axes_dict(mae_per_axis(t_true, tt[:, 2:5], tt[:, 1] > 0.5,
                                                      tl, sl))
        rep["truth_breakdown_mm"] = truth_breakdown(t, m, c, tl, sl, t_true, tt[:, 2:5],
                                                    tt[:, 1] > 0.5)
    return rep


def _wait_for_slave(sock: MasterSocket, endpoint: str, timeout_s: float = 5.0) -> None:
    """ZMQ_IMMEDIATE refuses to queue before the connection is up: wait for it."""
    t_end = time.monotonic() + timeout_s
    probe = P.encode_sample(P.Sample(0, 0.0, 0.0, math.nan, math.nan, math.nan, math.nan,
                                     False))
    # seq 0 with NaN: the slave counts it as malformed data and drops it, nothing moves.
    while time.monotonic() < t_end:
        if sock.send(probe):
            return
        time.sleep(0.01)
    raise TimeoutError(f"no slave answered at {endpoint} within {timeout_s:.0f} s: is "
                       "`teleop slave` running there, and are the CurveZMQ keys the same?")


def run_local_sim(states: Sequence[FingerState], cfg: TeleopConfig | None = None, *,
                  truth: np.ndarray | None = None, plot_path: str | None = None,
                  baseline: bool = True,
                  on_sample: Callable[[], None] | None = None) -> Session:
    """The demo: a simulated slave in a thread of this process on a random loopback port,
    driven over a real socket by run_session; optionally the Fig. 11 plot."""
    cfg = cfg or TeleopConfig()
    # The slave's thread (and ZeroMQ's, if this makes the first socket) inherit it.
    with (realtime_scheduling(cfg.link.rt_priority),
          SlaveThread(cfg, bind="tcp://127.0.0.1:*") as slave):
        session = run_session(states, slave.endpoint, cfg, truth=truth, baseline=baseline,
                              on_sample=on_sample)
    if plot_path is not None:
        session.plot(plot_path)
    return session
