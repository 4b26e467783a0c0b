"""Admission of samples (teleop/admission.py, docs/protocol.md): every drop reason, clocks
per master that no single sample can move, one owner at a time."""

from __future__ import annotations

import math

from teleop.admission import Admission
from teleop.config import SafetyConfig
from teleop.protocol import Sample

A, B = b"Ma", b"Mb"


def smp(seq, t, x=0.0, contact=True, force=1.0, t_send=None):
    return Sample(seq, t, t if t_send is None else t_send, x, 0.0, 1.0, force, contact)


def test_each_drop_reason_is_named_and_counted():
    """Slave clock = master clock + 100 s, latency 1 ms."""
    g = Admission(SafetyConfig(max_age_s=0.2, future_tolerance_s=0.05))
    off = 100.001
    assert g.judge(A, smp(1, 0.0), off + 0.0) is None
    assert g.judge(A, smp(2, 0.1, x=math.nan), off + 0.1) == "nonfinite"
    assert g.judge(A, smp(3, 0.2, x=math.inf), off + 0.2) == "nonfinite"
    assert g.judge(A, smp(4, 0.3), off + 0.3) is None
    assert g.judge(A, smp(4, 0.3), off + 0.31) == "duplicate"  # the last, replayed
    assert g.judge(A, smp(1, 0.0), off + 0.32) == "duplicate"  # an earlier one, replayed
    assert g.judge(A, smp(2, 0.05), off + 0.33) == "out_of_order"  # never accepted, late
    assert g.judge(A, smp(5, 0.25), off + 0.34) == "out_of_order"  # newer seq, older time
    assert g.judge(A, smp(6, 0.40, t_send=0.45), off + 0.45) is None
    assert g.judge(A, smp(7, 0.5, t_send=1.0), off + 1.0) == "stale"  # 0.5 s old
    assert g.judge(A, smp(8, 1.2, t_send=1.05), off + 1.05) == "future"  # 0.15 s ahead
    assert g.judge(A, smp(9 + 10_001, 1.06), off + 1.06) == "future"  # seq leaps
    assert g.judge(A, smp(10, 1.1, force=math.nan), off + 1.1) is None  # no load cell
    assert g.judge(A, Sample(11, 1.2, 1.2, math.nan, math.nan, 0.0, 0.0, False),
                   off + 1.2) is None  # lifted: no x, y
    assert g.judge(B, smp(1, 1.3), off + 1.3) == "not_owner"
    assert dict(g.dropped) == {"nonfinite": 2, "duplicate": 2, "out_of_order": 2, "stale": 1,
                               "future": 2, "not_owner": 1}
    assert g.dropped_total == 10


def stream(g, ident, seq0, t0, n, clock_offset_s, dt=0.01, latency_s=0.001):
    """n valid samples; returns the reasons (None: admitted)."""
    out = []
    for k in range(n):
        t = t0 + k * dt
        out.append(g.judge(ident, smp(seq0 + k, t), t + clock_offset_s + latency_s))
    return out


def test_no_single_sample_raises_the_bar_or_moves_the_clock():
    """After a valid stream, samples stamped t = 1e12, 1000 s ahead, with seq 2^64-1, or
    sent "from the future" (t_send far ahead) are dropped as future; the clock estimate
    moves by at most one rank of its window and the next valid samples are all admitted."""
    g = Admission(SafetyConfig())
    assert stream(g, A, 1, 0.0, 100, 50.0) == [None] * 100
    off0 = g.owner_offset_s()
    now = 50.0 + 1.0 + 0.001
    assert g.judge(A, smp(101, 1e12), now) == "future"
    assert g.judge(A, smp(102, 1000.0 + 1.0, t_send=1.0), now) == "future"
    assert g.judge(A, smp(2**64 - 1, 1.0), now) == "future"
    assert g.judge(A, smp(103, 1e6, t_send=-1e12), now) == "future"
    assert abs(g.owner_offset_s() - off0) < 1e-9
    assert stream(g, A, 104, 1.01, 50, 50.0) == [None] * 50


def test_one_owner_others_refused_until_it_is_released():
    """The first master with a valid sample owns the arm; another (10 s behind, or replaying
    the owner's samples) is refused as not_owner; after release (the slave's watchdog hold)
    the next valid master takes the arm with its own clock and sequence."""
    g = Admission(SafetyConfig())
    assert stream(g, A, 1, 0.0, 20, 5.0) == [None] * 20
    assert g.owner == A and g.acquired is False and g.takeovers == 1
    assert set(stream(g, B, 1, -10.0, 20, 15.0)) == {"not_owner"}
    assert set(stream(g, B, 1, 0.0, 20, 5.0)) == {"not_owner"}  # replay of A's samples
    assert g.release() == A
    r = stream(g, B, 1, -10.0, 20, 15.0)
    assert r == [None] * 20 and g.owner == B and g.takeovers == 2
    assert set(stream(g, A, 21, 0.2, 5, 5.0)) == {"not_owner"}


def test_the_same_master_restarted_with_its_clock_at_zero_takes_over_after_release():
    """Same routing id, clock and seq back at 0: refused while it still owns the arm
    (until the watchdog frees it), then admitted afresh."""
    g = Admission(SafetyConfig())
    assert stream(g, A, 1, 500.0, 20, 0.0) == [None] * 20
    assert set(stream(g, A, 1, 0.0, 5, 500.2)) == {"duplicate"}  # seqs 1-5 were accepted
    g.release()
    assert stream(g, A, 6, 0.05, 20, 500.2) == [None] * 20


def test_a_flood_of_new_peers_is_bounded():
    """Many connections: at most MAX_MASTERS tracked, the owner never forgotten."""
    from teleop.admission import MAX_MASTERS
    g = Admission(SafetyConfig())
    assert stream(g, A, 1, 0.0, 3, 0.0) == [None] * 3
    for k in range(500):
        assert g.judge(b"P" + k.to_bytes(4, "little"), smp(1, 0.05), 0.051) == "not_owner"
    assert len(g.tracks) <= MAX_MASTERS and A in g.tracks


def test_a_master_clock_jumping_ahead_costs_six_samples():
    """docs/protocol.md: the estimate is the 7th smallest of 64 delays, so after a jump of
    the master clock by 1 s, 6 samples are future and the 7th is admitted."""
    g = Admission(SafetyConfig())
    assert stream(g, A, 1, 0.0, 64, 10.0) == [None] * 64
    r = stream(g, A, 65, 0.64 + 1.0, 10, 9.0)  # master clock +1 s, slave clock continues
    assert r == ["future"] * 6 + [None] * 4
