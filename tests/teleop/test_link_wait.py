"""How the master and the slave wait for messages (``teleop.link.wait_readable``), over a
real DEALER/ROUTER pair on loopback.

zmq_poll counts whole milliseconds and pyzmq truncates a float timeout, so the former
waits of under 1 ms (every wait at 1 kHz, the last ms of each 2 ms slave tick) were busy
loops. These tests prove the wait wakes on a message, returns at its deadline, and
sleeps (uses little CPU) in between.
"""

from __future__ import annotations

import threading
import time

import zmq

from teleop.link import MasterSocket, SlaveSocket, wait_readable


def _pair():
    slave = SlaveSocket("tcp://127.0.0.1:*")
    master = MasterSocket(slave.endpoint)
    return slave, master


def test_wait_returns_at_the_deadline_without_spinning():
    slave, master = _pair()
    try:
        cpu0, t_end = time.process_time(), time.monotonic() + 0.3
        waits = 0
        while time.monotonic() < t_end:  # 0.5 ms deadlines, as at 1 kHz
            assert not wait_readable(slave.sock, time.monotonic() + 0.0005, time.monotonic)
            waits += 1
        cpu = time.process_time() - cpu0
        # A busy loop burns about the whole 0.3 s (measured 0.26 s with poll(int(0.5 ms)));
        # sleeping in select() leaves the CPU to others (measured ~0.02 s).
        assert cpu < 0.15, f"{cpu:.3f} s of CPU in 0.3 s of waiting ({waits} waits)"
    finally:
        master.close()
        slave.close()


def test_wait_wakes_on_a_message_before_its_deadline():
    slave, master = _pair()
    try:
        time.sleep(0.2)  # connected
        sender = threading.Timer(0.05, lambda: master.send(b"x"))
        sender.start()
        deadline = time.monotonic() + 10.0
        assert wait_readable(slave.sock, deadline, time.monotonic)
        assert time.monotonic() < deadline
        _ident, buf = slave.sock.recv_multipart(zmq.NOBLOCK)
        assert buf == b"x"
        # Nothing more: back to waiting until the deadline.
        assert not wait_readable(slave.sock, time.monotonic() + 0.01, time.monotonic)
        sender.join()
    finally:
        master.close()
        slave.close()
