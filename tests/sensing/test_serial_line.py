"""The serial line transport (vision/serial_line.py) is one module that the sensor board
and the accelerometer both use: the same framing, splitter, clock and pty emulator."""

from __future__ import annotations

import fydpad.accel.serial as accel_serial
import vision.sensors as sensors
from fydpad.accel.emulator import AccelEmulator
from vision import serial_line
from vision.board_emulator import BoardEmulator


def test_both_devices_use_the_one_transport():
    for name in ("frame_line", "unframe_line", "take_line", "DeviceClock", "LineError",
                 "ChecksumError"):
        assert getattr(accel_serial, name) is getattr(serial_line, name), name
        assert getattr(sensors, name) is getattr(serial_line, name), name
    assert issubclass(BoardEmulator, serial_line.PtyEmulator)
    assert issubclass(AccelEmulator, serial_line.PtyEmulator)


def test_a_cut_line_resyncs_on_the_next_dollar():
    good = serial_line.frame_line("D,1,2,3,4,5")
    buf = bytearray(b"$D,9,9" + good)  # a line cut short, then a whole one
    line, overlong = serial_line.take_line(buf)
    assert not overlong and serial_line.unframe_line(line) == ["D", "1", "2", "3", "4", "5"]
