"""Wire format of the master <-> slave link, version 2 (docs/protocol.md).

Every message is one ZeroMQ frame, little-endian, fixed size, starting with the
4-byte magic ``FYDT``, a version byte and a type byte. Positions are in the
workspace frame (docs/recording_format.md), millimetres; times are seconds of the
sender's monotonic clock.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from vision.errors import DeviceFault

MAGIC = b"FYDT"
VERSION = 2

TYPE_SAMPLE = 1
TYPE_STATE = 2

# Sample flags.
FLAG_CONTACT = 0x01
FLAG_HOLD_MODE = 0x02  # paper condition: the slave holds each sample, no prediction
FLAG_OPERATOR_HOLD = 0x04  # the operator holds the robot: stand still until released

# State status codes (one byte).
STATUS_IDLE = 0  # no valid sample yet
STATUS_TRACKING = 1
STATUS_CLUTCH = 2  # contact 0: x, y held, back to surface height
STATUS_WATCHDOG_HOLD = 3  # no valid sample for watchdog_s
STATUS_FAULT = 4  # robot fault (protective stop, connection lost): robot stopped
STATUS_OPERATOR_HOLD = 5  # the owner's samples carry the operator hold: standing still
STATUS_STOPPED = 6  # operator hold longer than safety.operator_hold_stop_s: robot stopped
STATUS_NOT_OWNER = 7  # (acknowledgement only) another master owns the arm: sample refused

# Why a state was sent.
REASON_TICK = 0
REASON_ACK = 1  # acknowledgement of an accepted sample
REASON_REFUSED = 2  # acknowledgement of a refused sample (the slave counted it as dropped)

_HEADER = "<4sBB"
# magic, version, type, flags u16, seq u64, t_capture f64, t_send f64, x, y, z, force f64
_SAMPLE = struct.Struct(_HEADER + "HQdddddd")
# magic, version, type, status u8, reason u8, echo_seq u64, t_echo_send f64 (master clock),
# t_echo_recv f64 (slave clock), t_slave f64, cmd xyz f64, actual xyz f64, received u32, dropped u32
_STATE = struct.Struct(_HEADER + "BBQdddddddddII")

SAMPLE_SIZE = _SAMPLE.size
STATE_SIZE = _STATE.size


class ProtocolError(DeviceFault, ValueError):
    """A message that is not a valid FYDT message of this version."""

    device = "link peer"
    check = "that master and slave run the same protocol version (docs/protocol.md)"


@dataclass(frozen=True, slots=True)
class Sample:
    """Master -> slave: one finger sample (workspace frame, mm)."""

    seq: int
    t_capture_s: float  # master clock, when the camera frame was taken
    t_send_s: float  # master clock, when the message left
    x_mm: float
    y_mm: float
    z_mm: float  # indentation, positive into the fabric
    force_n: float
    contact: bool
    hold_mode: bool = False
    operator_hold: bool = False


@dataclass(frozen=True, slots=True)
class State:
    """Slave -> master: what the robot does, with the clock-offset echo."""

    status: int
    reason: int
    echo_seq: int  # acknowledgement: that sample's seq; periodic: the newest admitted (0: none)
    t_echo_send_s: float  # that sample's t_send_s, master clock
    t_echo_recv_s: float  # when the slave read it, slave clock
    t_slave_s: float  # when this state was sampled, slave clock
    cmd_mm: tuple[float, float, float]  # commanded, workspace frame
    actual_mm: tuple[float, float, float]  # measured, workspace frame
    received: int
    dropped: int


def encode_sample(s: Sample) -> bytes:
    flags = ((FLAG_CONTACT if s.contact else 0) | (FLAG_HOLD_MODE if s.hold_mode else 0)
             | (FLAG_OPERATOR_HOLD if s.operator_hold else 0))
    return _SAMPLE.pack(MAGIC, VERSION, TYPE_SAMPLE, flags, s.seq, s.t_capture_s, s.t_send_s,
                        s.x_mm, s.y_mm, s.z_mm, s.force_n)


def encode_state(s: State) -> bytes:
    return _STATE.pack(MAGIC, VERSION, TYPE_STATE, s.status, s.reason, s.echo_seq,
                       s.t_echo_send_s, s.t_echo_recv_s, s.t_slave_s, *s.cmd_mm, *s.actual_mm,
                       s.received & 0xFFFFFFFF, s.dropped & 0xFFFFFFFF)


def _check_header(buf: bytes, msg_type: int, size: int) -> None:
    if len(buf) < 6:
        raise ProtocolError(f"message of {len(buf)} bytes is shorter than the 6-byte header")
    if buf[:4] != MAGIC:
        raise ProtocolError(f"bad magic {buf[:4]!r}, expected {MAGIC!r}")
    if buf[4] != VERSION:
        raise ProtocolError(f"unsupported protocol version {buf[4]}, this side speaks {VERSION}")
    if buf[5] != msg_type:
        raise ProtocolError(f"message type {buf[5]}, expected {msg_type}")
    if len(buf) != size:
        raise ProtocolError(f"message type {msg_type} has {len(buf)} bytes, expected {size}")


def decode_sample(buf: bytes) -> Sample:
    """Parse a sample; raises ProtocolError on anything malformed."""
    _check_header(buf, TYPE_SAMPLE, SAMPLE_SIZE)
    _, _, _, flags, seq, t_cap, t_send, x, y, z, force = _SAMPLE.unpack(buf)
    return Sample(seq, t_cap, t_send, x, y, z, force, bool(flags & FLAG_CONTACT),
                  bool(flags & FLAG_HOLD_MODE), bool(flags & FLAG_OPERATOR_HOLD))


def decode_state(buf: bytes) -> State:
    """Parse a state; raises ProtocolError on anything malformed."""
    _check_header(buf, TYPE_STATE, STATE_SIZE)
    v = _STATE.unpack(buf)
    return State(status=v[3], reason=v[4], echo_seq=v[5], t_echo_send_s=v[6],
                 t_echo_recv_s=v[7], t_slave_s=v[8], cmd_mm=(v[9], v[10], v[11]),
                 actual_mm=(v[12], v[13], v[14]), received=v[15], dropped=v[16])
