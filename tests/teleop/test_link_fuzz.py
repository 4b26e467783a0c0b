"""Property-based fuzzing of a real `teleop slave` process over loopback ZeroMQ.

Each example sends arbitrary bytes and arbitrary valid-looking samples (any flags, seqs,
times and values) from one to three connections, closes them, and then streams a valid
finger from a new connection. Properties: the slave stays alive; the command stays in the
safety box and under the speed limit; the valid stream is refused only as "not owner"
(while a fuzzing connection still owned the arm) and then followed. After all examples the
slave's report shows every watchdog trip, and so every release of the arm, came at the
first tick past the watchdog period: a valid stream owns the arm within one watchdog
period (plus a tick) of the other connections going silent.

Seeded (derandomize) and bounded (12 examples, about 25 s on a loaded 2-core machine).
"""

from __future__ import annotations

import json
import struct
import time

import numpy as np
import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from teleop import protocol as P
from teleop.config import TeleopConfig
from teleop.mapping import Mapping

from .helpers import Master, max_cmd_speed_mm_s, start_slave, stop, wait_for

CFG = TeleopConfig()
# The glide after a takeover at full speed: a fuzzing owner may leave the arm at the box's
# edge, and the examples should not spend seconds gliding back at 60 mm/s.
CFG.safety.resume_speed_mm_s = CFG.safety.max_speed_mm_s
# A slave process starved past max_age_s by a loaded machine would rightly drop the
# valid stream's samples as stale (a refusal other than "not owner"): 2 s, not 0.2 s.
CFG.safety.max_age_s = 2.0
MAPPING = Mapping(CFG.mapping)
BOX = np.array(CFG.safety.box_min_mm), np.array(CFG.safety.box_max_mm)

any_float = st.floats(width=64)
near = st.one_of(st.floats(-2.0, 2.0), st.floats(-1e3, 1e3),
                 st.sampled_from([0.0, 1e12, -1e12, 1e300, -1e300]), any_float)
value = st.one_of(st.floats(-300.0, 300.0), any_float)
# (flags, seq, capture time - now, send time - now, x, y, z, force)
sample_fields = st.tuples(st.integers(0, 0xFFFF), st.integers(0, 2**64 - 1), near, near,
                          value, value, value, value)
message = st.one_of(
    st.binary(max_size=128),
    st.binary(max_size=70).map(lambda b: b"FYDT\x02\x01" + b),
    sample_fields, sample_fields, sample_fields,
)


@st.composite
def plausible_stream(draw) -> list:
    """A stream a master could send (seq +1, capture times 10 ms apart ending now, finger
    in the workspace) with arbitrary messages mixed in: it may own the arm."""
    n = draw(st.integers(3, 30))
    seq0 = draw(st.integers(0, 2**64 - 1 - n))
    flags = draw(st.sampled_from([0x01, 0x03, 0x05, 0x00]))
    xs = draw(st.lists(st.floats(-200.0, 200.0), min_size=n, max_size=n))
    out: list = [(flags, seq0 + k, -0.01 * (n - k), -0.01 * (n - k), x, 0.0, 1.0, 1.0)
                 for k, x in enumerate(xs)]
    for _ in range(draw(st.integers(0, 3))):
        out.insert(draw(st.integers(0, len(out))), draw(message))
    return out


connections = st.lists(st.one_of(st.lists(message, min_size=1, max_size=40),
                                 plausible_stream()), min_size=1, max_size=3)


def encode(m, now: float) -> bytes:
    if isinstance(m, bytes):
        return m
    flags, seq, dt_cap, dt_send, x, y, z, f = m
    return struct.pack("<4sBBHQdddddd", P.MAGIC, P.VERSION, P.TYPE_SAMPLE, flags, seq,
                       now + dt_cap, now + dt_send, x, y, z, f)


@pytest.fixture(scope="module")
def slave(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "slave.toml").write_text(f"[safety]\nresume_speed_mm_s = "
                                  f"{CFG.safety.resume_speed_mm_s}\n"
                                  f"max_age_s = {CFG.safety.max_age_s}\n")
    proc, ep = start_slave("--report", str(d / "r.json"), "--config", str(d / "slave.toml"))
    yield proc, ep
    if proc.poll() is None:
        stop(proc)
    assert proc.returncode == 0
    rep = json.loads((d / "r.json").read_text())
    assert rep["watchdog_pre_trip_max_s"] <= CFG.safety.watchdog_s, rep


def in_box(states: list[P.State]) -> bool:
    cmd = [MAPPING.to_robot(np.array(s.cmd_mm)) for s in states]
    return all(np.all(c >= BOX[0] - 1e-9) and np.all(c <= BOX[1] + 1e-9) for c in cmd)


@settings(max_examples=12, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(conns=connections, target_x_mm=st.floats(-20.0, 20.0))
def test_fuzzing_connections_never_stop_the_slave_and_a_valid_stream_follows(slave, conns,
                                                                               target_x_mm):
    proc, ep = slave
    ctx = zmq.Context.instance()
    socks = []
    for msgs in conns:
        s = ctx.socket(zmq.DEALER)
        s.linger = 0
        s.connect(ep)
        socks.append(s)
        now = time.monotonic()
        for m in msgs:
            s.send(encode(m, now))
    for s in socks:  # give the sends time to leave, then silence
        s.close(linger=2000)
    assert proc.poll() is None, "the slave exited on input"
    m = Master(ep, x_mm=target_x_mm)
    try:
        def following() -> bool:
            t = m.ticks()
            return bool(t) and t[-1].status == P.STATUS_TRACKING and abs(
                t[-1].cmd_mm[0] - target_x_mm) < 0.3
        assert wait_for(following, 60.0)  # a hang guard
        assert proc.poll() is None
        refused = m.acks(P.REASON_REFUSED)
        assert {s.status for s in refused} <= {P.STATUS_NOT_OWNER}
        ticks = m.ticks()
        assert in_box(ticks)
        assert max_cmd_speed_mm_s(ticks) <= CFG.safety.max_speed_mm_s * (1 + 1e-6)
        # Silence, and wait for the slave to free the arm for the next example.
        m.paused = True
        assert wait_for(lambda: m.ticks()[-1].status == P.STATUS_WATCHDOG_HOLD, 30.0)
    finally:
        m.stop()
