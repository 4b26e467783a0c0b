"""The qbrobotics serial packet protocol (framing only; no I/O).

Followed from qbrobotics' own API, ``NMMI/qbAPI`` ``src/qbmove_communications.cpp``
(``commActivate``, ``commSetInputs``, ``commGetMeasurements``, ``commGetParamList``,
``RS485read``, ``checksum``) and ``src/commands.h`` (API v6.2.0), and its MATLAB twin in
``NMMI/qbmove-simulink`` (``additional_libraries/Bluetooth-Serial Device``):

    ':' ':' ID LEN CMD PAYLOAD... CHK

- ``ID``: the board's id (1-255; 0 addresses every board).
- ``LEN``: the bytes that follow it: command + payload + checksum.
- ``CHK``: XOR of ``CMD`` and the payload (the API's 8-bit "LCR" checksum).
- Multi-byte values are big-endian (the API swaps each short's bytes before sending).
- The board answers in the same frame; a data reply starts with the command code
  (``GET_MEASUREMENTS``: code, then one int16 per sensor, then CHK, LEN = 2 + 2n); an
  acknowledgment is ``ACK_OK ACK_OK`` (code and checksum of one byte).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

HEADER = b"::"

# Command codes (commands.h, enum qbmove_command).
CMD_PING = 0
CMD_GET_PARAM_LIST = 12
CMD_ACTIVATE = 128
CMD_GET_ACTIVATE = 129
CMD_SET_INPUTS = 130
CMD_GET_INPUTS = 131
CMD_GET_MEASUREMENTS = 132
CMD_GET_CURRENTS = 133
CMD_SET_WATCHDOG = 143
CMD_SET_INPUTS_ACK = 147

COMMAND_NAMES = {
    CMD_PING: "PING", CMD_GET_PARAM_LIST: "GET_PARAM_LIST", CMD_ACTIVATE: "ACTIVATE",
    CMD_GET_ACTIVATE: "GET_ACTIVATE", CMD_SET_INPUTS: "SET_INPUTS",
    CMD_GET_INPUTS: "GET_INPUTS", CMD_GET_MEASUREMENTS: "GET_MEASUREMENTS",
    CMD_GET_CURRENTS: "GET_CURRENTS", CMD_SET_INPUTS_ACK: "SET_INPUTS_ACK",
    CMD_SET_WATCHDOG: "SET_WATCHDOG",
}

# commands.h: activation byte of CMD_ACTIVATE (both motors on), acknowledgment values.
ACTIVATE_BOTH = 3
ACK_ERROR = 0
ACK_OK = 1

# commands.h, enum qbmove_control_mode.
CONTROL_ANGLE = 0
CONTROL_PWM = 1
CONTROL_CURRENT = 2
CURR_AND_POS_CONTROL = 3


def checksum(data: bytes | bytearray | memoryview) -> int:
    """XOR of every byte (qbAPI ``checksum``)."""
    c = 0
    for b in data:
        c ^= b
    return c


def encode(device_id: int, body: bytes) -> bytes:
    """A frame around ``body`` (command code + payload)."""
    if not 0 <= device_id <= 255:
        raise ValueError(f"device id must be 0-255, got {device_id}")
    if not 1 <= len(body) <= 254:
        raise ValueError(f"packet body must be 1-254 bytes, got {len(body)}")
    return HEADER + bytes((device_id, len(body) + 1)) + body + bytes((checksum(body),))


def command(device_id: int, cmd: int, payload: bytes = b"") -> bytes:
    return encode(device_id, bytes((cmd,)) + payload)


def int16s(*values: int) -> bytes:
    """Big-endian int16s (values clipped to the int16 range)."""
    return struct.pack(f">{len(values)}h", *(max(-32768, min(32767, int(v))) for v in values))


def parse_int16s(data: bytes) -> tuple[int, ...]:
    return struct.unpack(f">{len(data) // 2}h", data[: len(data) // 2 * 2])


@dataclass(frozen=True)
class Packet:
    device_id: int
    #: Command code + payload (checksum stripped).
    body: bytes


class PacketParser:
    """Incremental frame parser: feed bytes, collect packets; resynchronises on ``::``
    after garbage and counts what it dropped (``garbage_bytes``, ``checksum_errors``)."""

    def __init__(self, accept_ids: set[int] | frozenset[int] | None = None) -> None:
        #: Board ids a frame may carry (None: any). A header followed by another id is
        #: taken as stray bytes, so garbage ending in '::' cannot swallow a real frame
        #: behind a bogus length.
        self.accept_ids = accept_ids
        self._buf = bytearray()
        self.garbage_bytes = 0
        self.checksum_errors = 0

    def feed(self, data: bytes) -> list[Packet]:
        self._buf += data
        out: list[Packet] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # Keep a trailing ':' (it may start the next header).
                keep = 1 if buf.endswith(b":") else 0
                self.garbage_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if start:
                self.garbage_bytes += start
                del buf[:start]
            if len(buf) >= 3 and self.accept_ids is not None \
                    and buf[2] not in self.accept_ids:
                self.garbage_bytes += 1
                del buf[:1]
                continue
            if len(buf) < 4:
                break
            length = buf[3]
            if length < 2:
                # No command and checksum: not a frame. Skip this header and resync.
                self.garbage_bytes += 2
                del buf[:2]
                continue
            if len(buf) < 4 + length:
                break
            body = bytes(buf[4: 3 + length])
            if checksum(body) != buf[3 + length]:
                self.checksum_errors += 1
                # Drop the header only: the "frame" may have been garbage that contained
                # '::', with a real frame inside its would-be body.
                del buf[:2]
                continue
            out.append(Packet(buf[2], body))
            del buf[: 4 + length]
        return out

    def clear(self) -> None:
        self._buf.clear()
