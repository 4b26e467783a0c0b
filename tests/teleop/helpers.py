"""Real processes and sockets for the link tests (pyzmq test-fixture style: random ports,
linger 0, every receive with a timeout)."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import time
from pathlib import Path

import zmq

from teleop import protocol as P

REPO = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(REPO)}


def start_slave(*args: str, bind: str = "tcp://127.0.0.1:*",
                timeout_s: float = 20.0) -> tuple[subprocess.Popen, str]:
    """`teleop slave` in a subprocess; returns it and the endpoint it printed."""
    proc = subprocess.Popen([sys.executable, "-m", "teleop.cli", "slave", "--bind", bind, *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=ENV, cwd=REPO)
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        line = proc.stdout.readline()
        if "listening on" in line:
            return proc, line.split("listening on ")[1].split()[0]
        if proc.poll() is not None:
            break
    proc.kill()
    raise RuntimeError(f"slave did not start: {proc.stderr.read()}")


def stop(proc: subprocess.Popen, timeout_s: float = 10.0) -> str:
    """SIGINT (Ctrl-C), then the remaining stdout."""
    if proc.poll() is None:
        proc.send_signal(2)
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        raise
    return out


def dealer(endpoint: str, ctx: zmq.Context | None = None) -> zmq.Socket:
    ctx = ctx or zmq.Context.instance()
    s = ctx.socket(zmq.DEALER)
    s.linger = 0
    s.rcvtimeo = 2000
    s.connect(endpoint)
    return s


def sample(seq: int, t: float, x: float = 0.0, contact: bool = True) -> bytes:
    return P.encode_sample(P.Sample(seq, t, t, x, 0.0, 2.0, 1.0, contact))


def recv_states(sock: zmq.Socket, duration_s: float) -> list[P.State]:
    out = []
    t_end = time.monotonic() + duration_s
    while time.monotonic() < t_end:
        if sock.poll(max(1, int((t_end - time.monotonic()) * 1e3))):
            out.append(P.decode_state(sock.recv()))
    return out


def wait_for(pred, timeout_s: float = 60.0, step_s: float = 0.01) -> bool:
    """Wait on behaviour, not time: True as soon as ``pred()`` holds, False at the timeout."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if pred():
            return True
        time.sleep(step_s)
    return bool(pred())


def wait_line(stream, text: str, timeout_s: float) -> bool:
    """True once a line containing ``text`` is read from ``stream`` (a process's pipe),
    False at the timeout (a hang guard: what is awaited is the process's own log)."""
    import threading
    found = threading.Event()

    def read() -> None:
        for line in stream:
            if text in line:
                found.set()
                return

    threading.Thread(target=read, daemon=True).start()
    return found.wait(timeout_s)


class Master:
    """A master in a thread of the test process: its own DEALER (random routing id, as
    MasterSocket), a finger held at ``x_mm`` (contact), streamed at ``rate_hz`` with a clock
    ``time.monotonic() + clock_offset_s`` (or from 0 at start: ``clock_from_zero``).
    Every state received is kept as (arrival, state)."""

    def __init__(self, endpoint: str, x_mm: float = 0.0, rate_hz: float = 100.0,
                 clock_offset_s: float = 0.0, clock_from_zero: bool = False,
                 routing_id: bytes | None = None, first_seq: int = 1) -> None:
        import threading

        from teleop.link import master_routing_id
        self.ctx = zmq.Context()
        self.sock = self.ctx.socket(zmq.DEALER)
        self.sock.linger = 0
        self.routing_id = routing_id or master_routing_id()
        self.sock.setsockopt(zmq.ROUTING_ID, self.routing_id)
        self.sock.connect(endpoint)
        self.x_mm = x_mm
        self.operator_hold = False  # the samples' operator-hold flag, from now on
        self.paused = False  # True: send nothing, keep reading states
        self.injected: list[bytes] = []  # sent once each on this socket, before the next sample
        self.period_s = 1.0 / rate_hz
        t0 = time.monotonic()
        self.offset_s = (-t0 if clock_from_zero else clock_offset_s)
        self.seq = first_seq
        self.sent: list[bytes] = []
        self.states: list[tuple[float, P.State]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def clock(self) -> float:
        return time.monotonic() + self.offset_s

    def _run(self) -> None:
        t_next = time.monotonic()
        while not self._stop.is_set():
            t = self.clock()
            msg = P.encode_sample(P.Sample(self.seq, t, t, self.x_mm, 0.0, 1.0, 1.0, True,
                                           operator_hold=self.operator_hold))
            while self.injected:
                self.sock.send(self.injected.pop(0))
            if not self.paused:
                self.seq += 1
                self.sent.append(msg)
                self.sock.send(msg)
            t_next += self.period_s
            while True:
                wait_ms = max(0, int((t_next - time.monotonic()) * 1e3))
                if not self.sock.poll(wait_ms):
                    break
                self.states.append((time.monotonic(), P.decode_state(self.sock.recv())))
            if time.monotonic() - t_next > 0.1:  # starved: no burst
                t_next = time.monotonic()

    def acks(self, reason: int) -> list[P.State]:
        return [st for _, st in list(self.states) if st.reason == reason]

    def ticks(self) -> list[P.State]:
        return self.acks(P.REASON_TICK)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self.sock.close(linger=0)
        self.ctx.term()


def max_cmd_speed_mm_s(states: list[P.State]) -> float:
    """Largest |d cmd| / d t_slave between consecutive periodic states (the slave's clock:
    independent of how fast this machine runs)."""
    v = 0.0
    for a, b in itertools.pairwise(states):
        dt = b.t_slave_s - a.t_slave_s
        if dt > 0:
            d = sum((p - q) ** 2 for p, q in zip(b.cmd_mm, a.cmd_mm, strict=True)) ** 0.5
            v = max(v, d / dt)
    return v
