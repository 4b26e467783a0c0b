"""The operator hold end to end, the message size limit, refused CurveZMQ handshakes, and
the report's loss count across a slave restart: real sockets and `teleop slave` processes."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import time

import pytest
import zmq
import zmq.auth

from fydpad.station.link import StationLink
from teleop import protocol as P
from teleop.config import SafetyConfig, TeleopConfig
from teleop.link import MAX_MSG_SIZE
from teleop.master import StreamLog, _dropped
from teleop.slave import SlaveThread
from vision.state import FingerState

from .helpers import Master, max_cmd_speed_mm_s, start_slave, stop, wait_for

SAFETY = SafetyConfig()
#: For tests whose masters are threads of this process and whose subject is not the
#: watchdog: a loaded machine may starve them for a second, and the slave would hold.
NOT_THE_SUBJECT_WATCHDOG_S = 5.0


def finger(x_mm: float) -> FingerState:
    return FingerState(t_s=time.monotonic(), contact=True, x_mm=x_mm, y_mm=0.0,
                       indentation_mm=1.0, force_n=1.0)


def test_operator_hold_from_the_station_link_holds_at_once_and_resumes_gliding(tmp_path):
    """StationLink.set_operator_hold(True) against a real slave process: one sample goes out
    at once and the slave stands still (status "operator hold") while the finger moves
    40 mm; on release it glides there no faster than safety.resume_speed_mm_s."""
    cfg_path = tmp_path / "slave.toml"
    # The test thread is the master: starved past the watchdog by a loaded machine, the
    # slave would hold and count the operator hold again when it resumes. Not the subject.
    cfg_path.write_text(f"[safety]\nwatchdog_s = {NOT_THE_SUBJECT_WATCHDOG_S}\n")
    proc, ep = start_slave("--report", str(tmp_path / "r.json"), "--config", str(cfg_path))
    link = StationLink(ep, TeleopConfig())
    seen: list[P.State] = []

    def pump(x_mm: float, until, timeout_s: float = 20.0) -> bool:
        def step() -> bool:
            link.send(finger(x_mm))
            if link.slave is not None and (not seen or link.slave != seen[-1]):
                seen.append(link.slave)
            return until()
        return wait_for(step, timeout_s)

    def at(x_mm: float):
        return lambda: (link.slave is not None and link.slave.reason == P.REASON_TICK
                        and link.slave.status == P.STATUS_TRACKING
                        and abs(link.slave.cmd_mm[0] - x_mm) < 0.3)

    def held_ticks(since: int) -> list[P.State]:
        return [s for s in seen[since:] if s.reason == P.REASON_TICK
                and s.status == P.STATUS_OPERATOR_HOLD]

    try:
        assert pump(20.0, at(20.0))
        assert not link.operator_hold
        sent = link.sent
        link.set_operator_hold(True)
        assert link.operator_hold and link.sent == sent + 1  # sent at once, no frame waited
        n0 = len(seen)
        assert wait_for(lambda: (link._drain(), seen.append(link.slave), held_ticks(n0))[2],
                        10.0)
        assert pump(-20.0, lambda: len(held_ticks(n0)) >= 30)  # the finger moves away
        assert all(abs(s.cmd_mm[0] - 20.0) < 0.3 for s in held_ticks(n0))  # the arm not
        link.set_operator_hold(False)
        n1 = len(seen)
        assert pump(-20.0, at(-20.0))
        glide = [s for s in seen[n1:] if s.reason == P.REASON_TICK]
        assert max_cmd_speed_mm_s(glide) <= SAFETY.resume_speed_mm_s * (1 + 1e-6)
    finally:
        link.close()
    stop(proc)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["operator_holds"] == 1 and not rep["stopped"]


BIG_SENDER = """
import sys, zmq, zmq.utils.monitor
s = zmq.Context.instance().socket(zmq.DEALER)
s.linger = 0
mon = s.get_monitor_socket(zmq.EVENT_DISCONNECTED)
s.connect(sys.argv[1])
s.send(b"\\0" * 100_000_000)
print("cut off" if mon.poll(30_000) and zmq.utils.monitor.recv_monitor_message(mon)["event"]
      == zmq.EVENT_DISCONNECTED else "still connected", flush=True)
"""


def test_the_operator_hold_may_be_set_from_another_thread_while_frames_are_sent():
    """A key or web handler thread toggles the hold while the vision loop sends: every
    sample reaches the slave whole (none malformed) and the last one carries the hold."""
    import threading

    cfg = TeleopConfig()
    cfg.safety.watchdog_s = NOT_THE_SUBJECT_WATCHDOG_S
    with SlaveThread(cfg) as sl:
        link = StationLink(sl.endpoint, cfg)
        try:
            assert wait_for(lambda: (link.send(finger(0.0)), link.slave is not None)[1], 60.0)

            def toggle() -> None:
                for k in range(200):
                    link.set_operator_hold(k % 2 == 0)
                link.set_operator_hold(True)

            th = threading.Thread(target=toggle)
            th.start()
            for _ in range(300):
                link.send(finger(1.0))
            th.join(10.0)
            # (A full send queue drops samples at the master, counted: that is by design.)
            total = link.sent
            assert wait_for(lambda: sl.loop.counts["received"] == total, 60.0)
            assert sl.loop.counts["malformed"] == 0
            assert link.operator_hold
            assert wait_for(lambda: (link.send(finger(1.0)), sl.loop._latest.operator_hold)[1],
                            10.0)
        finally:
            link.close()


def test_master_stream_carries_the_operator_hold(caplog):
    """teleop.master.stream(operator_hold=...) against a slave over a real socket: the
    samples in the held span carry the flag; the slave stands still there, says so once,
    and releases and tracks again after it."""
    from teleop.link import MasterSocket
    from teleop.master import stream
    from teleop.trajectories import circle, finger_stream

    states, _ = finger_stream(circle(), 2.0)
    cfg = TeleopConfig()
    # Master and slave are threads of this process: starved together by a loaded machine,
    # the slave would hold on its watchdog and drop late samples as stale (their own
    # tests), and count the operator hold again when it resumes. Not the subject here.
    cfg.safety.watchdog_s = cfg.safety.max_age_s = NOT_THE_SUBJECT_WATCHDOG_S
    with (caplog.at_level("INFO", logger="teleop.slave"), SlaveThread(cfg) as sl,
          MasterSocket(sl.endpoint, cfg.link) as sock):
        stream(states, sock, preroll_s=0.3, operator_hold=lambda t: 0.5 <= t < 1.2)
        # Tracking again after the hold, by the slave's own status (a starved slave may
        # take the held and the following samples in one drain: the master's states need
        # not show a held tick; test_operator_hold_from_the_station_link checks those).
        assert wait_for(lambda: sl.loop.status == P.STATUS_TRACKING
                        and not sl.loop._latest.operator_hold, 60.0)
        assert sl.loop.counts["operator_holds"] == 1
    said = [r.getMessage() for r in caplog.records if r.name == "teleop.slave"]
    assert sum(m.startswith("operator hold: standing still") for m in said) == 1, said
    assert sum(m.startswith("operator hold released after") for m in said) == 1, said


def test_a_100_mb_message_is_cut_off_without_stalling_the_slave(tmp_path):
    """ZMQ_MAXMSGSIZE (4096 bytes): a process sending 100 MB is disconnected by libzmq from
    the frame header; the slave never reads it, the streaming master keeps the arm and the
    watchdog never trips while the master sends. (The sender is its own process: building
    100 MB holds this process's interpreter for seconds on a loaded machine, and the
    master thread with it; the slave's watchdog is 1 s for the same reason.)"""
    cfg_path = tmp_path / "slave.toml"
    cfg_path.write_text("[safety]\nwatchdog_s = 1.0\n")
    proc, ep = start_slave("--report", str(tmp_path / "r.json"), "--config", str(cfg_path))
    m = Master(ep, x_mm=3.0)
    try:
        assert wait_for(lambda: len(m.ticks()) > 50, 60.0)
        big = subprocess.run([sys.executable, "-c", BIG_SENDER, ep], capture_output=True,
                             text=True, timeout=60)
        assert big.stdout.strip() == "cut off", big.stderr
        n = len(m.acks(P.REASON_ACK))
        assert wait_for(lambda: len(m.acks(P.REASON_ACK)) > n + 50, 60.0), (
            "the master's samples were not acknowledged after the big message",
            m._thread.is_alive(), len(m.sent), [(s.reason, s.status) for _, s in m.states[-5:]])
        stop(proc)  # while the master still streams: its end would trip the watchdog
    finally:
        m.stop()
        if proc.poll() is None:
            proc.kill()
    rep = json.loads((tmp_path / "r.json").read_text())
    # A trip is allowed only when this process's master thread itself fell silent for the
    # watchdog period (a starved test process), never when it kept sending.
    sent_gap_s = max(b.t_send_s - a.t_send_s for a, b in itertools.pairwise(
        [P.decode_sample(msg) for msg in m.sent]))
    assert rep["watchdog_trips"] == 0 or sent_gap_s > 1.0, (rep, sent_gap_s)
    assert rep["malformed"] == 0
    # The big one never reached the loop: every message was a whole sample. (Not all were
    # accepted: one a starved slave read past safety.max_age_s is dropped as stale.)
    assert rep["messages"] == rep["received"]
    assert MAX_MSG_SIZE == 4096


@pytest.fixture
def curve(tmp_path):
    from teleop.keys import generate
    keys = tmp_path / "keys"
    generate(keys)
    cfg = TeleopConfig()
    cfg.link.curve = "on"
    cfg.link.keys_dir = str(keys)
    return cfg, keys, tmp_path


def client_options(kind: str, keys, tmp_path) -> dict:
    server_pub, _ = zmq.auth.load_certificate(keys / "server.key")
    if kind == "no_keys":
        return {}
    if kind == "unknown_client_key":
        pub, sec = zmq.auth.load_certificate(
            zmq.auth.create_certificates(tmp_path, "intruder")[1])
        return dict(curve_publickey=pub, curve_secretkey=sec, curve_serverkey=server_pub)
    other_pub, _ = zmq.auth.load_certificate(zmq.auth.create_certificates(tmp_path, "o")[0])
    pub, sec = zmq.auth.load_certificate(keys / "client.key_secret")
    return dict(curve_publickey=pub, curve_secretkey=sec, curve_serverkey=other_pub)


@pytest.mark.parametrize("kind", ["no_keys", "unknown_client_key", "wrong_server_key"])
def test_every_refused_handshake_is_counted_and_logged(curve, kind, caplog):
    """A client without keys, with a key not in authorized_clients/, or holding the wrong
    server key: refused, counted by kind from the socket monitor (the first and the last
    never reach ZAP), logged; the slave never sees a message from it."""
    cfg, keys, tmp_path = curve
    with caplog.at_level("WARNING", logger="teleop.link"), SlaveThread(cfg) as sl:
        s = zmq.Context.instance().socket(zmq.DEALER)
        s.linger = 0
        for k, v in client_options(kind, keys, tmp_path).items():
            setattr(s, k, v)
        s.connect(sl.endpoint)
        try:
            s.send(b"x", zmq.NOBLOCK)
        except zmq.Again:
            pass
        assert wait_for(lambda: sl.sock.handshakes_failed[kind] >= 1, 60.0)
        assert set(sl.sock.handshakes_failed) == {kind}
        assert sl.loop.counts["messages"] == 0
        s.close()
        rep = sl.loop.report()
    assert rep["handshakes_failed"][kind] >= 1
    assert any("refused a CurveZMQ handshake" in r.message and kind in r.message
               for r in caplog.records)


def state(received: int, dropped: int) -> tuple[float, P.State]:
    return (0.0, P.State(P.STATUS_TRACKING, P.REASON_ACK, 1, 0.0, 0.0, 0.0, (0.0,) * 3,
                         (0.0,) * 3, received, dropped))


def test_dropped_differences_each_slave_process_on_its_own():
    """A pass that saw the slave restart: 100 sent; the first slave received samples
    1-40 (none refused, counters up to 1040 from before), 10 were lost in the restart, the
    second counted 1-50 and refused 2. Lost + refused = 10 + 2 (subtracting counters of
    the two processes would give 1040 - ...)."""
    log = StreamLog(sent=100)
    log.states = ([state(1000 + k, 7) for k in range(1, 41)]
                  + [state(k, 2 if k > 30 else 0) for k in range(1, 51)])
    assert _dropped(log) == 12
