"""The live station's tele-operation link: the latest finger state to the slave at the
vision rate, the slave's state back, the operator hold in every sample, and "hold" on the
way out (paper III-C; docs/protocol.md)."""

from __future__ import annotations

import math
import threading
import time

import zmq

from teleop import protocol as P
from teleop.config import TeleopConfig
from teleop.link import MasterSocket
from vision.state import FingerState


class StationLink:
    """Sends each finger state as it is made; never waits (a full queue drops the sample:
    the slave acts on the newest one anyway). Thread-safe: the vision loop sends while a
    key, web or pedal handler sets the operator hold from its own thread (a ZeroMQ socket
    is used under one lock)."""

    def __init__(self, endpoint: str, cfg: TeleopConfig | None = None):
        self.cfg = cfg or TeleopConfig()
        self.endpoint = endpoint
        self._sock = MasterSocket(endpoint, self.cfg.link)
        self._seq = 1
        self.sent = 0
        self.send_failed = 0
        #: The slave's newest state (None until it answers).
        self.slave: P.State | None = None
        self._answered_at = math.nan  # monotonic time of the slave's newest state
        self._operator_hold = False
        self._last_state: FingerState | None = None
        self._lock = threading.RLock()

    @property
    def operator_hold(self) -> bool:
        """True while the operator holds the robot (every sample carries the flag)."""
        return self._operator_hold

    def set_operator_hold(self, on: bool) -> None:
        """Hold (True) or release (False) the robot. Every following sample carries the
        flag; one is sent now (the last finger state again, or "no contact" before any), so
        the slave stands still without waiting for the next frame. On release the slave
        glides back to the finger at ``safety.resume_speed_mm_s``."""
        with self._lock:
            on = bool(on)
            if on == self._operator_hold:
                return
            self._operator_hold = on
            last = self._last_state
            self.send(last if last is not None else FingerState.no_contact(time.monotonic()))

    def answer_age_s(self) -> float:
        """Seconds since the slave last answered (inf before it ever has): a slave that
        answered once and then went silent is not a live link."""
        return math.inf if math.isnan(self._answered_at) else (
            time.monotonic() - self._answered_at)

    def send(self, state: FingerState) -> None:
        with self._lock:
            self._send(state)

    def _send(self, state: FingerState) -> None:
        self._last_state = state
        now = time.monotonic()
        if state.contact:
            z = state.indentation_mm if math.isfinite(state.indentation_mm) else 0.0
            x, y = state.x_mm, state.y_mm
        else:
            x = y = math.nan
            z = 0.0
        force = state.force_n if math.isfinite(state.force_n) else math.nan
        sample = P.Sample(self._seq, now, now, x, y, z, force, bool(state.contact),
                          operator_hold=self._operator_hold)
        self._seq += 1
        if self._sock.send(P.encode_sample(sample)):
            self.sent += 1
        else:
            self.send_failed += 1
        self._drain()

    def _drain(self) -> None:
        while True:
            try:
                buf = self._sock.sock.recv(zmq.NOBLOCK)
            except zmq.Again:
                return
            try:
                self.slave = P.decode_state(buf)
                self._answered_at = time.monotonic()
            except P.ProtocolError:
                pass

    def tracking_error_mm(self, state: FingerState) -> float:
        """Distance in the workspace between the finger and where the slave is now."""
        if self.slave is None or not state.contact:
            return math.nan
        ax, ay, _ = self.slave.actual_mm
        return math.hypot(ax - state.x_mm, ay - state.y_mm)

    def hold(self) -> None:
        """Tell the robot to hold: the finger lifted (the slave's clutch holds x and y)."""
        self.send(FingerState.no_contact(time.monotonic()))
        time.sleep(0.05)
        with self._lock:
            self._drain()

    def close(self) -> None:
        with self._lock:
            self._sock.close()
