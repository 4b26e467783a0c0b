"""Real-time scheduling of the slave (teleop/realtime.py): asked for, inherited, or refused."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from teleop.realtime import realtime_scheduling, request_realtime
from tests.teleop.helpers import ENV, REPO, start_slave, stop

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.mark.skipif(not IS_ROOT, reason="SCHED_FIFO needs root or CAP_SYS_NICE here")
def test_slave_runs_every_thread_under_sched_fifo() -> None:
    """Proves the slave asks before it starts its threads: ZeroMQ's I/O threads inherit it."""
    proc, _ = start_slave("--rt-priority", "7", "--duration", "3")
    try:
        tids = [int(t) for t in os.listdir(f"/proc/{proc.pid}/task")]
        policies = {tid: os.sched_getscheduler(tid) for tid in tids}
        priorities = {tid: os.sched_getparam(tid).sched_priority for tid in tids}
    finally:
        out = stop(proc)
    assert len(tids) >= 2, "expected the main thread and ZeroMQ's I/O thread"
    assert set(policies.values()) == {os.SCHED_FIFO}, policies
    assert set(priorities.values()) == {7}, priorities
    report = json.loads(out.strip().splitlines()[-1])
    assert report["scheduling"] == "SCHED_FIFO 7"


def test_slave_with_rt_priority_zero_stays_normal() -> None:
    proc, _ = start_slave("--rt-priority", "0", "--duration", "3")
    try:
        policy = os.sched_getscheduler(proc.pid)
    finally:
        out = stop(proc)
    assert policy == os.SCHED_OTHER
    assert json.loads(out.strip().splitlines()[-1])["scheduling"] == "normal"


def test_refused_request_runs_on_at_normal_priority_and_says_how_to_permit() -> None:
    """Proves a user without the right gets a working process and a message, not a crash.

    As root the child runs without CAP_SYS_NICE (util-linux setpriv drops it from the
    bounding set before exec), so the kernel really refuses.
    """
    code = ("import os, sys; sys.path.insert(0, sys.argv[1]);"
            "from teleop.realtime import request_realtime;"
            "print(request_realtime(30)); print(os.sched_getscheduler(0) == os.SCHED_OTHER)")
    cmd = [sys.executable, "-c", code, str(REPO)]
    if IS_ROOT:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            pytest.skip("setpriv (util-linux) is needed to drop CAP_SYS_NICE as root")
        cmd = [setpriv, "--bounding-set", "-sys_nice", *cmd]
    out = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=30,
                         check=True).stdout.splitlines()
    assert out[0].startswith("normal (SCHED_FIFO 30 not permitted: run as root"), out
    assert out[1] == "True"


def test_out_of_range_priority_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="0 \\(off\\) or 1-99, got 120"):
        request_realtime(120)
    proc = subprocess.run([sys.executable, "-m", "teleop.cli", "slave", "--bind",
                           "tcp://127.0.0.1:*", "--rt-priority", "-3"], capture_output=True,
                          text=True, env=ENV, cwd=REPO, timeout=60)
    assert proc.returncode == 2
    assert "--rt-priority: real-time priority must be 0 (off) or 1-99, got -3" in proc.stderr


def test_stream_pauses_the_collector_and_restores_it() -> None:
    """Proves the master's stream runs without generation-2 collections (they stalled it
    55-175 ms at 1 kHz, docs/teleop.md) and leaves the collector as it found it."""
    import gc

    from teleop.link import MasterSocket, SlaveSocket
    from teleop.master import stream
    from teleop.trajectories import circle, finger_stream

    states, _ = finger_stream(circle(), 0.05, fps=200.0, noise_mm=0.0)
    seen: list[bool] = []

    def watched():
        for fs in states:
            seen.append(gc.isenabled())
            yield fs

    with SlaveSocket("tcp://127.0.0.1:*") as slave, MasterSocket(slave.endpoint) as sock:
        for enabled_before in (True, False):
            (gc.enable if enabled_before else gc.disable)()
            seen.clear()
            try:
                log = stream(watched(), sock, preroll_s=0.0, tail_s=0.0)
                after = gc.isenabled()
            finally:
                gc.enable()
            assert len(seen) == len(states) and log.t_s
            assert not any(seen), "the collector ran during the stream"
            assert after is enabled_before


def test_slave_run_in_process_leaves_the_caller_on_its_own_scheduling() -> None:
    """Proves a caller (here pytest) is not left on SCHED_FIFO by an in-process slave: it
    would pass it on to every process it starts afterwards."""
    from teleop.cli import main

    before = (_policies(), os.sched_getaffinity(0))
    assert main(["slave", "--bind", "tcp://256.0.0.1:1", "--curve", "off",
                 "--rt-priority", "20"]) == 2  # fails to bind, after asking for SCHED_FIFO
    policies, cpus = _policies(), os.sched_getaffinity(0)
    assert cpus == before[1]
    assert {tid: policies[tid] for tid in before[0] if tid in policies} == {
        tid: pol for tid, pol in before[0].items() if tid in policies}
    assert (os.SCHED_FIFO, 20) not in policies.values()


def _policies() -> dict[int, tuple[int, int]]:
    """Every thread of this process: (policy, priority)."""
    out = {}
    for t in os.listdir("/proc/self/task"):
        try:
            out[int(t)] = (os.sched_getscheduler(int(t)), os.sched_getparam(int(t)).sched_priority)
        except ProcessLookupError:
            pass
    return out


@pytest.mark.skipif(not IS_ROOT, reason="SCHED_FIFO needs root or CAP_SYS_NICE here")
def test_scheduling_block_covers_every_thread_and_undoes_it_after() -> None:
    """Proves what the demo relies on: inside the block every thread runs SCHED_FIFO, the
    ones already there (ZeroMQ's I/O thread of an earlier session) and the ones started
    in it (the in-process slave); after it every thread is back, none left on SCHED_FIFO
    (the review found ZeroMQ's threads left there)."""
    import threading

    import zmq

    from teleop.link import SlaveSocket

    zmq.Context.instance()  # its I/O threads exist before the block
    before = _policies()
    hold = threading.Event()
    seen: list[int] = []

    def worker() -> None:
        seen.append(os.sched_getscheduler(0))
        hold.wait(10)

    with realtime_scheduling(11) as got:
        inside_before = {tid: _policies().get(tid) for tid in before}
        t = threading.Thread(target=worker)
        t.start()
        with SlaveSocket("tcp://127.0.0.1:*"):
            inside_all = _policies()
    after = _policies()
    hold.set()
    t.join()
    assert got == "SCHED_FIFO 11"
    assert seen == [os.SCHED_FIFO]
    assert set(inside_before.values()) == {(os.SCHED_FIFO, 11)}
    assert set(inside_all.values()) == {(os.SCHED_FIFO, 11)}
    assert {tid: after[tid] for tid in before} == before
    assert all(pol == (os.SCHED_OTHER, 0) for tid, pol in after.items() if tid not in before)


def test_a_bad_rt_priority_in_a_config_file_names_the_file_and_field(tmp_path) -> None:
    from fydpad.config import ConfigError, load_config
    from teleop.cli import load_config as load_teleop_config

    bad = tmp_path / "slave.toml"
    bad.write_text("[link]\nrt_priority = 120\n")
    with pytest.raises(SystemExit, match=rf"{bad}: link.rt_priority must be 0 .* got 120"):
        load_teleop_config(str(bad))
    station = tmp_path / "station.toml"
    station.write_text("[teleop.link]\nrt_priority = -1\n")
    with pytest.raises(ConfigError, match=rf"{station}: .*link.rt_priority must be 0 .* got -1"):
        load_config(station)
