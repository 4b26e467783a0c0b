"""The QB Robotics PSoC board that drives the pad's two motors (paper II-A), over serial.

Framing and command codes: :mod:`fydpad.motors.qb_protocol` (from qbrobotics' qbAPI).
Two control modes (``QbBoardConfig.control_mode``; ``docs/motors.md`` weighs them):

- ``"pwm"`` (default; the firmware's ``CONTROL_PWM``): the board applies the duty the
  host sends; the host runs the position loop and eq. (3) at 1 kHz, reading the
  encoders (``GET_MEASUREMENTS``, a reply per tick) and writing the duties
  (``SET_INPUTS``, no reply).
- ``"position"`` (``CONTROL_ANGLE``): the board runs its own position loop; the host
  sends position references (softness position + vibration as a position offset).

Every read has a deadline: a board that does not answer gives a :class:`QbTimeoutError`
naming the port, the board id and the command, never a hang. The 1 kHz loop's read waits
at most ``tick_timeout_s`` (half a tick): a late reply reuses the last reading and is
taken by a later tick. Replies with a bad checksum and stray bytes are skipped and
counted (``stats()``).

The board stops by itself: activation arms the firmware's watchdog (``watchdog_cs``,
qbAPI's ``commSetWatchDog``), so a host that dies or hangs leaves the motors unpowered
within 20 ms, not at their last duty.
"""

from __future__ import annotations

import math
import select
import time
from dataclasses import dataclass
from types import TracebackType

import serial

from fydpad.motors import qb_protocol as qp
from fydpad.motors.base import MotorConfig, MotorError


class QbTimeoutError(MotorError):
    """The board did not answer in time."""


class QbProtocolError(MotorError):
    """The board answered something that does not fit the protocol."""


@dataclass(frozen=True)
class QbBoardConfig:
    """Serial link and firmware settings of the QB board."""

    port: str = "/dev/ttyUSB0"
    #: qbAPI's fast rate (BAUD_RATE_T_2000000); 460800 on older firmware.
    baudrate: int = 2_000_000
    device_id: int = 1
    #: Deadline for a reply to a set-up command (ping, activate, parameters), s.
    timeout_s: float = 0.1
    #: The most a tick's measurement read waits, s: half the 1 kHz period, so a late
    #: reply never holds the tick past its deadline (the last reading is reused).
    tick_timeout_s: float = 0.0005
    #: Ticks in a row without a reply tolerated (the last reading is reused) before the
    #: read fails and the station goes to its safe state: 10 ms at 1 kHz, inside the
    #: board's 20 ms watchdog.
    max_missed_replies: int = 10
    #: "pwm" (host position loop, eq. 3 literal) or "position" (board position loop).
    control_mode: str = "pwm"
    #: Encoder counts per turn in the measurements (16-bit angle, resolution shift 0).
    counts_per_rev: int = 65536
    #: The input value that means full PWM in CONTROL_PWM (firmware scale).
    pwm_full_scale: int = 100
    #: Index of the control-mode entry in the firmware's parameter list, set with
    #: CMD_GET_PARAM_LIST (qbAPI v6 commGetParamList); check it with your firmware's
    #: parameter list (index 0 prints it). -1: leave the board's mode as stored.
    control_mode_param_index: int = 6
    #: Encoder sensors the board reports (the FYD-pad's two motor encoders).
    n_sensors: int = 2
    #: Per-tick encoder reads one tick behind (see ``QbMotors.read_positions_rad``).
    pipelined: bool = True
    #: The firmware watchdog, centiseconds (qbAPI ``commSetWatchDog(wdt)``, 0-500 cs,
    #: sent as wdt / 2: the firmware counts in 2 cs steps). No command for this long and
    #: the board deactivates its motors. Default: the shortest, 2 cs = 20 ms (20 ticks
    #: at 1 kHz). 0 disarms it: the board would keep its last duty if the host died.
    watchdog_cs: int = 2


class QbMotors:
    """:class:`~fydpad.motors.base.MotorPair` on a QB board (pyserial)."""

    def __init__(self, config: QbBoardConfig = QbBoardConfig(),
                 motor_config: MotorConfig | None = None) -> None:
        if config.control_mode not in ("pwm", "position"):
            raise MotorError(f"QB board: control_mode must be 'pwm' or 'position', "
                             f"got {config.control_mode!r}")
        if not (config.watchdog_cs == 0 or 2 <= config.watchdog_cs <= 500):
            raise MotorError(f"QB board: watchdog_cs must be 0 (off) or 2-500 centiseconds "
                             f"(the firmware counts in 2 cs steps), got {config.watchdog_cs}")
        self.config = config
        self.motor_config = motor_config if motor_config is not None else MotorConfig()
        self.port = config.port
        self._parser = qp.PacketParser(accept_ids=frozenset((config.device_id,)))
        self._rad_per_count = 2.0 * math.pi / config.counts_per_rev
        self._last = (math.nan, math.nan)
        self._missed = 0
        self._in_flight = 0  # measurement requests sent, not yet answered
        self.timeouts = 0
        #: Ticks that reused the last reading (no reply within ``tick_timeout_s``).
        self.reused_readings = 0
        self.active = False
        self.last_error = ""
        try:
            # Non-blocking reads: the deadline is kept here (select), not by pyserial,
            # whose timeout setter reconfigures the port (too slow per tick).
            self._ser = serial.Serial(
                config.port, baudrate=config.baudrate, timeout=0,
                write_timeout=config.timeout_s, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise MotorError(f"QB board: cannot open {config.port}: {exc}") from None
        self._fd = self._ser.fileno()

    # ---------------------------------------------------------------- transport

    def _send(self, cmd: int, payload: bytes = b"") -> None:
        frame = qp.command(self.config.device_id, cmd, payload)
        try:
            self._ser.write(frame)
        except (serial.SerialException, OSError) as exc:
            raise MotorError(f"QB board on {self.port}: write failed ({exc})") from None

    def _request(self, cmd: int, payload: bytes = b"", timeout_s: float | None = None) -> bytes:
        """Send a command and return the body of the board's reply (code + data)."""
        # As qbAPI does: drop whatever is pending, so an old reply is never taken for
        # this one.
        try:
            self._ser.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            raise MotorError(f"QB board on {self.port}: {exc}") from None
        self._parser.clear()
        self._in_flight = 0
        self._send(cmd, payload)
        return self._read_reply(cmd, self.config.timeout_s if timeout_s is None else timeout_s)

    def _read_reply(self, cmd: int, timeout_s: float, want: int | None = None) -> bytes:
        """The next reply from this board (``want``: the next one starting with that
        code and long enough for the sensors, others are skipped)."""
        deadline = time.monotonic() + timeout_s
        bad0 = self._parser.checksum_errors
        junk0 = self._parser.garbage_bytes
        ser = self._ser
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            try:
                ready, _, _ = select.select([self._fd], [], [], remaining)
                if not ready:
                    continue
                chunk = ser.read(max(1, ser.in_waiting))
            except (serial.SerialException, OSError) as exc:
                raise MotorError(f"QB board on {self.port}: read failed ({exc})") from None
            if not chunk:
                continue
            for pkt in self._parser.feed(chunk):
                if want is None:
                    return pkt.body
                if pkt.body[0] == want and len(pkt.body) >= 1 + 2 * self.config.n_sensors:
                    return pkt.body
        self.timeouts += 1
        name = qp.COMMAND_NAMES.get(cmd, str(cmd))
        bad = self._parser.checksum_errors - bad0
        junk = self._parser.garbage_bytes - junk0
        extra = ""
        if bad or junk:
            extra = f" ({bad} reply(ies) with a bad checksum, {junk} stray byte(s))"
        raise QbTimeoutError(
            f"QB board on {self.port}: no valid reply to {name} from device "
            f"{self.config.device_id} within {timeout_s * 1000:.0f} ms{extra}")

    # ---------------------------------------------------------------- commands

    def ping(self) -> None:
        """Check the board answers (CMD_PING)."""
        self._request(qp.CMD_PING)

    def set_control_mode(self, mode: str) -> None:
        """Store the control mode in the board's parameters (CMD_GET_PARAM_LIST set)."""
        value = {"pwm": qp.CONTROL_PWM, "position": qp.CONTROL_ANGLE}[mode]
        idx = self.config.control_mode_param_index
        if idx < 0:
            return
        reply = self._request(qp.CMD_GET_PARAM_LIST, idx.to_bytes(2, "big") + bytes((value,)))
        if reply[:1] != bytes((qp.ACK_OK,)):
            raise QbProtocolError(f"QB board on {self.port}: control mode {mode!r} refused "
                                  f"(parameter index {idx}; reply {reply.hex()})")

    def get_activate(self) -> int:
        reply = self._request(qp.CMD_GET_ACTIVATE)
        if len(reply) < 2 or reply[0] != qp.CMD_GET_ACTIVATE:
            raise QbProtocolError(f"QB board on {self.port}: unexpected GET_ACTIVATE reply "
                                  f"{reply.hex()}")
        return reply[1]

    def activate(self) -> None:
        """Ping, set the control mode, power the motors and check they are on."""
        self.ping()
        self.set_control_mode(self.config.control_mode)
        self._send(qp.CMD_SET_WATCHDOG, bytes((self.config.watchdog_cs // 2,)))
        # Hold still on power-up: zero duty, or the current position as the reference.
        if self.config.control_mode == "pwm":
            self._send(qp.CMD_SET_INPUTS, qp.int16s(0, 0))
        else:
            p = self._get_counts(self.config.timeout_s)
            self._send(qp.CMD_SET_INPUTS, qp.int16s(p[0], p[1]))
        self._send(qp.CMD_ACTIVATE, bytes((qp.ACTIVATE_BOTH,)))
        state = self.get_activate()
        if state != qp.ACTIVATE_BOTH:
            raise MotorError(f"QB board on {self.port}: motors did not activate "
                             f"(activation byte {state})")
        self.active = True

    def deactivate(self) -> None:
        """Vibration off, motors to rest, power off. Never raises (errors kept in
        ``last_error``): it is the fail-safe path."""
        try:
            if self.config.control_mode == "pwm":
                # Zero duty: the pretensioned fabric brings the unpowered rollers back to
                # their rest stop.
                self._send(qp.CMD_SET_INPUTS, qp.int16s(0, 0))
            else:
                r0, r1 = self.motor_config.rest_theta_rad
                self._send(qp.CMD_SET_INPUTS, qp.int16s(self._counts(r0), self._counts(r1)))
        except MotorError as exc:
            self.last_error = str(exc)
        try:
            self._send(qp.CMD_ACTIVATE, bytes((0,)))
        except MotorError as exc:
            self.last_error = str(exc)
        self.active = False

    def _counts(self, theta_rad: float) -> int:
        return round(theta_rad / self._rad_per_count)

    def set_positions_rad(self, theta0_rad: float, theta1_rad: float) -> None:
        if self.config.control_mode != "position":
            raise MotorError(f"QB board on {self.port}: position references need "
                             "control_mode = 'position'")
        c = self.motor_config
        r0 = min(max(theta0_rad, c.theta_min_rad), c.theta_max_rad)
        r1 = min(max(theta1_rad, c.theta_min_rad), c.theta_max_rad)
        self._send(qp.CMD_SET_INPUTS, qp.int16s(self._counts(r0), self._counts(r1)))

    def set_pwm(self, duty0: float, duty1: float) -> None:
        if self.config.control_mode != "pwm":
            raise MotorError(f"QB board on {self.port}: PWM inputs need control_mode = 'pwm'")
        full = self.config.pwm_full_scale
        d0 = min(max(duty0, -1.0), 1.0)
        d1 = min(max(duty1, -1.0), 1.0)
        self._send(qp.CMD_SET_INPUTS, qp.int16s(round(d0 * full), round(d1 * full)))

    def _get_counts(self, timeout_s: float) -> tuple[int, ...]:
        reply = self._request(qp.CMD_GET_MEASUREMENTS, timeout_s=timeout_s)
        if reply[0] != qp.CMD_GET_MEASUREMENTS or len(reply) < 1 + 2 * self.config.n_sensors:
            raise QbProtocolError(f"QB board on {self.port}: unexpected GET_MEASUREMENTS "
                                  f"reply {reply.hex()}")
        return qp.parse_int16s(reply[1:])

    def read_positions_rad(self) -> tuple[float, float]:
        """Both encoders (GET_MEASUREMENTS), waiting at most ``tick_timeout_s``. No reply
        in time reuses the last reading (counted in ``reused_readings``); more than
        ``max_missed_replies`` ticks in a row without one raise :class:`QbTimeoutError`.

        Pipelined (``QbBoardConfig.pipelined``): this tick takes the newest reply to the
        requests of earlier ticks and sends the next request, so a USB round trip (about
        1 ms with the FTDI latency timer at 1 ms) never stalls the 1 kHz tick; the position
        loop sees encoders a tick or two old, which its ~10 Hz bandwidth does not notice.
        At most two requests are in flight: a reply later than that is taken as lost."""
        try:
            if self.config.pipelined:
                p = self._pipelined_counts()
            else:
                p = self._get_counts(self.config.tick_timeout_s)
        except QbTimeoutError:
            self._missed += 1
            if self._missed > self.config.max_missed_replies or math.isnan(self._last[0]):
                raise
            self.reused_readings += 1
            return self._last
        self._missed = 0
        self._last = (p[0] * self._rad_per_count, p[1] * self._rad_per_count)
        return self._last

    def _pipelined_counts(self) -> tuple[int, ...]:
        try:
            if math.isnan(self._last[0]) and self._in_flight == 0:
                return self._get_counts(self.config.timeout_s)  # the first: set-up time
            return self._newest_measurement()
        finally:  # the next request goes out whatever this tick got
            if self._in_flight >= 2:
                self._in_flight -= 1  # the oldest request's reply is late past use: lost
            self._send(qp.CMD_GET_MEASUREMENTS)
            self._in_flight += 1

    def _newest_measurement(self) -> tuple[int, ...]:
        """The newest measurement reply to arrive within ``tick_timeout_s`` (all those
        already there are taken, the newest kept); QbTimeoutError if none."""
        want = 1 + 2 * self.config.n_sensors
        newest = None
        for pkt in self._poll_packets(self.config.tick_timeout_s):
            if pkt.body[0] == qp.CMD_GET_MEASUREMENTS and len(pkt.body) >= want:
                newest = pkt.body
                self._in_flight = max(0, self._in_flight - 1)
        if newest is None:
            self.timeouts += 1
            raise QbTimeoutError(
                f"QB board on {self.port}: no valid reply to GET_MEASUREMENTS from device "
                f"{self.config.device_id} within {self.config.tick_timeout_s * 1000:.1f} ms")
        return qp.parse_int16s(newest[1:])

    def _poll_packets(self, timeout_s: float) -> list:
        """Every packet already received, or (none yet) the first to arrive within
        ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        ser = self._ser
        packets: list = []
        while True:
            try:
                ready, _, _ = select.select([self._fd], [], [],
                                            max(0.0, deadline - time.monotonic()))
                chunk = ser.read(max(1, ser.in_waiting)) if ready else b""
            except (serial.SerialException, OSError) as exc:
                raise MotorError(f"QB board on {self.port}: read failed ({exc})") from None
            if chunk:
                packets += self._parser.feed(chunk)
                continue  # more may be there already
            if packets or time.monotonic() >= deadline:
                return packets

    def stats(self) -> dict:
        return {"timeouts": self.timeouts,
                "checksum_errors": self._parser.checksum_errors,
                "garbage_bytes": self._parser.garbage_bytes}

    def close(self) -> None:
        try:
            self._ser.close()
        except (serial.SerialException, OSError):
            pass

    def __enter__(self) -> QbMotors:
        try:
            self.activate()
        except BaseException:
            self.deactivate()
            self.close()
            raise
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            self.deactivate()
        finally:
            self.close()
