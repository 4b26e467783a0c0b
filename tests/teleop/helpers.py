"""Real processes and sockets for the link tests (pyzmq test-fixture style: random ports,
linger 0, every receive with a timeout)."""

from __future__ import annotations

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
