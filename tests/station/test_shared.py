"""The seqlock hand-off between processes: never a torn read, always the newest value."""

from __future__ import annotations

import math
import multiprocessing as mp

import numpy as np
import pytest

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
    # Attaching must not reset the values to NaN under a published sequence.
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


def _bare_station():
    """A Station as the web view sees it: its control record and writer, no loops."""
    from fydpad.station.render import RenderSpec
    from fydpad.station.station import Station, StationOptions

    return Station(None, None, None, StationOptions(render=RenderSpec(realtime=False)))


def test_control_writers_in_many_threads_lose_no_change():
    """The web thread (settings, stimuli, staircase) and the station (its epoch) change the
    control record at once: every change lands, no field ever goes back to an older value,
    and the sequence ends even (a torn ``+= 1`` would leave it odd)."""
    import sys
    import threading

    from fydpad.station.render import CONTROL_FIELDS
    from fydpad.web.experiment import Stimulus
    from fydpad.web.server import StationStimulus

    station = _bare_station()
    n = 3000
    fields = ("vibration_gain", "epoch_s", "friction_b_v")
    stimulus = StationStimulus(station)
    go = threading.Event()
    done = threading.Event()
    backwards: list[tuple[str, float, float]] = []

    def writer(name: str) -> None:
        go.wait()
        for i in range(1, n + 1):
            station.set_control(**{name: float(i)})

    def stimuli() -> None:  # the experiment's presenter, through the same writer
        go.wait()
        for i in range(1, n + 1):
            stimulus(Stimulus("s", float(i), 0.0, "", None))

    def reader() -> None:
        last = dict.fromkeys((*fields, "stiffness_n_per_mm"), -1.0)
        while not done.is_set():
            _, v = station.control.read(timeout_s=1.0)  # not for ever on a stuck sequence
            for name in last:
                x = float(v[CONTROL_FIELDS.index(name)])
                if x == x and x < last[name]:
                    backwards.append((name, last[name], x))
                last[name] = x if x == x else last[name]

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: interleave writes
    try:
        threads = [threading.Thread(target=writer, args=(f,)) for f in fields]
        threads.append(threading.Thread(target=stimuli))
        watch = threading.Thread(target=reader)
        for th in (*threads, watch):
            th.start()
        go.set()
        for th in threads:
            th.join(60)
        done.set()
        watch.join(60)
    finally:
        sys.setswitchinterval(old)
    assert backwards == []  # no change overwritten by an older read-modify-write
    assert int(station.control._view[0]) % 2 == 0
    seq, v = station.control.read(timeout_s=1.0)
    assert seq == 1 + 4 * n  # every write counted: the initial one and 4 n changes
    got = dict(zip(CONTROL_FIELDS, v, strict=True))
    assert [got[f] for f in (*fields, "stiffness_n_per_mm")] == [float(n)] * 4
    with pytest.raises(KeyError, match="unknown control field 'gain'"):
        station.set_control(gain=1.0)


def test_a_read_gives_up_on_a_sequence_left_odd():
    """A writer killed mid-write leaves the sequence odd for good: a reader with a timeout
    returns the last consistent values instead of spinning for ever."""
    rec = SharedRecord(("a", "b"))
    rec.write([1.0, 2.0])
    seq, v = rec.read(timeout_s=0.01)
    assert seq == 1 and v.tolist() == [1.0, 2.0]
    rec._view[0] += 1.0  # the writer died between its two increments
    rec._view[1:] = (7.0, 8.0)  # half-written values are never handed out
    seq, v = rec.read(timeout_s=0.01)
    assert seq == 1 and v.tolist() == [1.0, 2.0] and rec.stale_reads == 1
    fresh = SharedRecord._attach(rec.fields, rec.raw)  # never read a consistent value
    assert fresh.read(timeout_s=0.01)[0] == 0
    with pytest.raises(ValueError, match="2 values expected"):
        rec.write([1.0, 2.0, 3.0])  # refused before the sequence moves


def test_a_bad_write_leaves_the_sequence_even():
    rec = SharedRecord(("a", "b"))
    with pytest.raises(ValueError):
        rec.write([1.0, "x"])
    assert int(rec._view[0]) % 2 == 0 and rec.read(timeout_s=0.01)[0] == 0


def test_render_process_stops_though_the_control_record_is_stuck_mid_write():
    """The render process (a real one) keeps ticking on the last consistent control when
    the station died mid-write, and still stops on request, posting its statistics."""
    import queue

    from fydpad.station.render import CONTROL_FIELDS, RenderSpec, render_main

    ctx = mp.get_context("spawn")
    state = SharedFingerState()
    state.publish(FingerState(t_s=0.0, contact=False), arrival_s=0.0, frame=0)
    control = SharedRecord(CONTROL_FIELDS)
    control.write([1.0, math.nan, 1.0, 0.0, 0.0, math.nan, 0.0])
    stop, ready, results = ctx.Event(), ctx.Event(), ctx.Queue()
    p = ctx.Process(target=render_main, args=(RenderSpec(realtime=False), state, control,
                                              stop, results, ready), daemon=True)
    p.start()
    try:
        from fydpad.station.station import StationOptions
        # The station's own start deadline: a hang guard (a loaded machine starts slowly).
        assert ready.wait(5 * StationOptions().render_start_timeout_s)
        control._view[0] += 1.0  # odd from now on: a writer that never finished
        # Two live reports after that: the loop ticked a whole second on a stuck record.
        lives = 0
        while lives < 2:
            kind, _ = results.get(timeout=60)
            lives += kind == "live"
        stop.set()
        p.join(60)
        assert not p.is_alive() and p.exitcode == 0
        posted = []
        while True:
            try:
                posted.append(results.get(timeout=10))
            except queue.Empty:
                break
            if posted[-1][0] == "stats":
                break
        stats = dict(posted)["stats"]["render"]
        assert stats["stale_reads"] > 0
    finally:
        if p.is_alive():
            p.kill()
