"""The seqlock hand-off between processes: never a torn read, always the newest value."""

from __future__ import annotations

import multiprocessing as mp

import numpy as np

from fydpad.station.shared import SharedFingerState, SharedRecord
from vision.state import FingerState


def _writer(rec: SharedRecord, n: int, done) -> None:
    for i in range(1, n + 1):
        rec.write(np.full(len(rec.fields), float(i)))
    done.set()


def test_no_torn_reads_across_processes():
    ctx = mp.get_context("spawn")
    rec = SharedRecord(tuple(f"f{i}" for i in range(16)))
    done = ctx.Event()
    p = ctx.Process(target=_writer, args=(rec, 200_000, done))
    p.start()
    reads = 0
    last = 0.0
    while not done.is_set() or reads == 0:
        seq, v = rec.read()
        if seq:
            assert np.all(v == v[0]), v  # every field from the same write
            assert v[0] >= last  # never older than what was already seen
            last = v[0]
            reads += 1
    p.join(timeout=10)
    assert p.exitcode == 0
    seq, v = rec.read()
    assert seq == 200_000 and v[0] == 200_000.0


def test_finger_state_round_trip():
    s = SharedFingerState()
    assert s.latest() == (0, None)
    st = FingerState(t_s=1.5, contact=True, x_mm=3.0, y_mm=-4.0, indentation_mm=2.0,
                     speed_mm_s=12.0, force_n=0.5)
    s.publish(st, arrival_s=10.0, frame=45)
    seq, got = s.latest()
    assert seq == 1 and got == st


def _attach_and_report(shared: SharedFingerState, out) -> None:
    out.put(shared.latest())


def test_attaching_in_another_process_keeps_the_published_state():
    # Regression: attaching used to reset the values to NaN under a published sequence.
    ctx = mp.get_context("spawn")
    s = SharedFingerState()
    st = FingerState(t_s=2.0, contact=True, x_mm=1.0, y_mm=2.0)
    s.publish(st, arrival_s=1.0, frame=7)
    out = ctx.Queue()
    p = ctx.Process(target=_attach_and_report, args=(s, out))
    p.start()
    seq, got = out.get(timeout=30)
    p.join(timeout=10)
    assert seq == 1 and got.x_mm == 1.0
    assert s.latest()[1].x_mm == 1.0  # and the parent still sees it
