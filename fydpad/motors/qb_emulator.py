"""An emulated QB board on a pseudo-terminal, speaking the same packet protocol.

The host side (:class:`~fydpad.motors.qb.QbMotors`) opens ``emulator.port`` (the pty's
slave end) like a USB serial port. Behind it the emulator runs the simulated plant
(:mod:`fydpad.motors.sim`): each ``SET_INPUTS`` is one board tick: in PWM mode the
duty drives the plant, in position mode the board's own position loop does. Faults can
be injected for tests: no replies (``mute``), replies with a bad checksum
(``corrupt_replies``), stray bytes before a reply (``garbage_before_reply``), replies
sent late (``reply_delay_s``).

Like the firmware, it ignores frames with a bad checksum or another board's id, and
enforces its watchdog (``CMD_SET_WATCHDOG``): armed with byte b, the board deactivates
its motors (unpowered) when no frame for it arrives for b * 2 cs. The board
clock is ``time.monotonic``; the expiry is kept at the exact deadline, as the firmware's
hardware counter fires there (``watchdog_stops``: (last frame, stop) times), and
applied when the emulator next looks (its thread wakes at the deadline).
"""

from __future__ import annotations

import heapq
import math
import os
import select
import threading
import time
import tty
from types import TracebackType

from fydpad.motors import qb_protocol as qp
from fydpad.motors.base import MotorConfig
from fydpad.motors.control import PositionLoop
from fydpad.motors.sim import FabricMotorPlant


class QbEmulator:
    """A QB board with two motor encoders on a pty (``start``/``stop`` or ``with``)."""

    def __init__(self, device_id: int = 1, plant: FabricMotorPlant | None = None,
                 counts_per_rev: int = 65536, pwm_full_scale: int = 100,
                 control_mode_param_index: int = 6, n_sensors: int = 2,
                 motor_config: MotorConfig | None = None) -> None:
        self.device_id = device_id
        self.plant = plant if plant is not None else FabricMotorPlant()
        self.plant.powered = False
        self.counts_per_rev = counts_per_rev
        self.pwm_full_scale = pwm_full_scale
        self.control_mode_param_index = control_mode_param_index
        self.n_sensors = n_sensors
        mc = motor_config if motor_config is not None else MotorConfig()
        self._loop = PositionLoop(mc.kp_duty_per_rad, mc.ki_duty_per_rad_s,
                                  mc.kd_duty_s_per_rad, self.plant.config.dt_s, 1.0)
        self.control_mode = qp.CONTROL_ANGLE  # the firmware's default mode
        self.activation = 0
        #: The watchdog byte as the firmware got it (period: 2 cs per unit; 0: off).
        self.watchdog = 0
        #: Board time of the last frame for this board, and each watchdog stop as
        #: (last frame before it, the stop) board times.
        self.last_frame_s = math.nan
        self.watchdog_stops: list[tuple[float, float]] = []
        self.inputs = (0, 0)
        # Fault injection.
        self.mute = False
        self.corrupt_replies = 0
        self.garbage_before_reply = b""
        self.reply_delay_s = 0.0
        self._delayed: list[tuple[float, int, bytes]] = []  # (due, order, frame)
        self._order = 0
        # What the host sent (command codes, in order) and what was ignored.
        self.received: list[int] = []
        self.bad_frames = 0
        self._parser = qp.PacketParser(accept_ids=frozenset((device_id, 0)))
        self._lock = threading.Lock()
        self._master = -1
        self._slave = -1
        self._stop_r, self._stop_w = -1, -1
        self._thread: threading.Thread | None = None
        self.port = ""

    # ----------------------------------------------------------------- lifecycle

    def start(self) -> QbEmulator:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # bytes as they are: no echo, no CR/LF translation
        tty.setraw(self._master)
        self.port = os.ttyname(self._slave)
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._run, name="qb-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        if self._thread is not None:
            os.write(self._stop_w, b"x")
            self._thread.join(timeout=2.0)
            self._thread = None
        for fd in (self._master, self._slave, self._stop_r, self._stop_w):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = self._stop_r = self._stop_w = -1

    def __enter__(self) -> QbEmulator:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    @property
    def watchdog_period_s(self) -> float:
        return self.watchdog * 0.02

    def _run(self) -> None:
        while True:
            with self._lock:
                timeout = self._next_event_s()
            ready, _, _ = select.select([self._master, self._stop_r], [], [], timeout)
            if self._stop_r in ready:
                return
            with self._lock:
                self._apply_watchdog()
                self._send_due_replies()
            if self._master not in ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:
                return
            bad0 = self._parser.checksum_errors
            with self._lock:
                for pkt in self._parser.feed(data):
                    if pkt.device_id not in (self.device_id, 0):
                        continue
                    self._apply_watchdog()  # a frame after the deadline comes too late
                    self.last_frame_s = time.monotonic()
                    reply = self._handle(pkt.body)
                    if reply is not None:
                        self._reply(reply)
                self.bad_frames += self._parser.checksum_errors - bad0

    def _next_event_s(self) -> float | None:
        """Seconds to the next watchdog deadline or delayed reply (None: none)."""
        due = []
        if self.watchdog and self.activation and not math.isnan(self.last_frame_s):
            due.append(self.last_frame_s + self.watchdog_period_s)
        if self._delayed:
            due.append(self._delayed[0][0])
        return max(0.0, min(due) - time.monotonic()) if due else None

    def _apply_watchdog(self) -> None:
        """The firmware's watchdog: past its deadline, motors off (as of the deadline)."""
        if not (self.watchdog and self.activation) or math.isnan(self.last_frame_s):
            return
        deadline = self.last_frame_s + self.watchdog_period_s
        if time.monotonic() >= deadline:
            self.activation = 0
            self.plant.powered = False  # unpowered: no drive whatever the duty register
            self._loop.reset()
            self.watchdog_stops.append((self.last_frame_s, deadline))

    def at_rest(self) -> bool:
        """Motors unpowered (the watchdog applied as of now)."""
        with self._lock:
            self._apply_watchdog()
            return not self.activation and not self.plant.powered

    def send_delayed_replies(self) -> None:
        """Send every delayed reply now, due or not (a test holds replies with a long
        ``reply_delay_s`` and lets them through at a point of its choosing)."""
        with self._lock:
            while self._delayed:
                os.write(self._master, heapq.heappop(self._delayed)[2])

    def _send_due_replies(self) -> None:
        now = time.monotonic()
        while self._delayed and self._delayed[0][0] <= now:
            os.write(self._master, heapq.heappop(self._delayed)[2])

    def _reply(self, body: bytes) -> None:
        if self.mute:
            return
        frame = bytearray(qp.encode(self.device_id, body))
        if self.corrupt_replies > 0:
            self.corrupt_replies -= 1
            frame[-1] ^= 0xFF
        out = self.garbage_before_reply + bytes(frame)
        if self.reply_delay_s > 0:
            self._order += 1
            heapq.heappush(self._delayed, (time.monotonic() + self.reply_delay_s,
                                           self._order, out))
            return
        os.write(self._master, out)

    # ------------------------------------------------------------------ firmware

    def _counts(self, theta_rad: float) -> int:
        return round(theta_rad * self.counts_per_rev / (2.0 * math.pi))

    def _handle(self, body: bytes) -> bytes | None:
        cmd = body[0]
        data = body[1:]
        self.received.append(cmd)
        p = self.plant
        if cmd == qp.CMD_PING:
            return bytes((qp.CMD_PING,))
        if cmd == qp.CMD_ACTIVATE and len(data) >= 1:
            self.activation = data[0]
            p.powered = data[0] != 0
            self._loop.reset()
            return None  # the firmware does not answer ACTIVATE
        if cmd == qp.CMD_SET_WATCHDOG and len(data) >= 1:
            self.watchdog = data[0]
            return None
        if cmd == qp.CMD_GET_ACTIVATE:
            return bytes((qp.CMD_GET_ACTIVATE, self.activation))
        if cmd in (qp.CMD_SET_INPUTS, qp.CMD_SET_INPUTS_ACK) and len(data) >= 4:
            self.inputs = qp.parse_int16s(data[:4])
            self._tick()
            return bytes((qp.ACK_OK, )) if cmd == qp.CMD_SET_INPUTS_ACK else None
        if cmd == qp.CMD_GET_INPUTS:
            return bytes((qp.CMD_GET_INPUTS,)) + qp.int16s(*self.inputs)
        if cmd == qp.CMD_GET_MEASUREMENTS:
            th = [p.encoder_rad(0), p.encoder_rad(1)]
            th += [0.5 * (th[0] + th[1])] * (self.n_sensors - 2)
            return bytes((qp.CMD_GET_MEASUREMENTS,)) + qp.int16s(
                *(self._counts(t) for t in th[: self.n_sensors]))
        if cmd == qp.CMD_GET_PARAM_LIST and len(data) >= 2:
            idx = int.from_bytes(data[:2], "big")
            if idx == self.control_mode_param_index and len(data) >= 3 and data[2] in (
                    qp.CONTROL_ANGLE, qp.CONTROL_PWM, qp.CONTROL_CURRENT,
                    qp.CURR_AND_POS_CONTROL):
                self.control_mode = data[2]
                return bytes((qp.ACK_OK,))
            return bytes((qp.ACK_ERROR,))
        return None  # unknown command: the firmware stays silent

    def _tick(self) -> None:
        """One board tick with the current inputs."""
        p = self.plant
        if self.activation:
            if self.control_mode == qp.CONTROL_PWM:
                full = self.pwm_full_scale
                p.set_duty(self.inputs[0] / full, self.inputs[1] / full)
            else:
                k = 2.0 * math.pi / self.counts_per_rev
                u = self._loop.update(self.inputs[0] * k, self.inputs[1] * k,
                                      p.encoder_rad(0), p.encoder_rad(1))
                p.set_duty(u[0], u[1])
        else:
            p.set_duty(0.0, 0.0)
        p.step()
