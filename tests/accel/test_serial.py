"""The real pyserial accelerometer reader against the emulated device over a pseudo-terminal:
a 1 kHz stream, garbage, cut lines, bad checksums, dropped samples, counter and clock
wraps, a device reset, a stalled device, an unplugged one, a wrong device, a missing port.

Every read has the reader's own stall timeout, so nothing can hang: 0.2 s where a test
waits for the error, 5 s elsewhere (generous, so a starved emulator thread on a busy
machine does not fail a test that expects data).
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

from fydpad.accel import open_accelerometer
from fydpad.accel.base import AccelError
from fydpad.accel.emulator import AccelEmulator
from fydpad.accel.serial import (
    DEFAULT_BAUD,
    G_M_S2,
    AccelInfo,
    SerialAccelerometer,
    accel_data_line,
    accel_hello_line,
    parse_accel_line,
)
from vision.board_emulator import BoardEmulator
from vision.sensors import DeviceClock, frame_line

ERROR_TIMEOUT_S = 0.2
DATA_TIMEOUT_S = 5.0
LSB = 3900e-6 * G_M_S2


def counting(k: int) -> tuple[float, float, float]:
    """Sample k carries k in its counts, so every row can be checked against its index."""
    return (k % 1000) * LSB, -(k % 500) * LSB, 256 * LSB


def read_n(acc: SerialAccelerometer, n: int, limit: int = 2000) -> np.ndarray:
    blocks, got = [], 0
    for _ in range(limit):
        b = acc.read(timeout_s=0.05)
        blocks.append(b)
        got += len(b)
        if got >= n:
            return np.vstack(blocks)
    raise AssertionError(f"only {got} of {n} samples arrived")


def read_until_error(acc: SerialAccelerometer, limit: int = 10_000) -> AccelError:
    acc.timeout_s = ERROR_TIMEOUT_S
    for _ in range(limit):
        try:
            acc.read(timeout_s=0.05)
        except AccelError as exc:
            return exc
    raise AssertionError("the reader never reported the fault")


def scripted(**kw) -> AccelEmulator:
    """A device that sends only what the test tells it to (plus its hello)."""
    return AccelEmulator(counting, **kw).start(streaming=False)


def test_a_1khz_stream_arrives_whole_and_scaled():
    with AccelEmulator(counting, rate_hz=1000).start() as emu, \
            SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        a = read_n(acc, 300)
        assert b"?" in emu.commands
        assert acc.info == AccelInfo("FYDPAD-ACCEL", 1, 1000.0, 3900.0, 16.0, "ADXL345")
        assert acc.rate_hz == 1000.0
        lost_on_link = emu.dropped_bytes > 0
    k = np.rint(a[:, 1] / LSB).astype(int)  # sample index mod 1000, from the data itself
    step = np.rint(np.diff(a[:, 0]) * 1000).astype(int)
    assert a[0, 0] == 0.0
    if not lost_on_link:
        assert acc.stats.dropped == 0 and acc.stats.bad_lines == 0
        assert np.all(step == 1)
        np.testing.assert_allclose(np.diff(a[:, 0]), 1e-3, atol=1e-9)  # the device clock
    # Where samples are missing, the device time and the counter agree on how many.
    np.testing.assert_array_equal((k[0] + np.cumsum(np.r_[0, step])) % 1000, k)
    np.testing.assert_allclose(a[:, 2], -np.rint(-a[:, 2] / LSB) * LSB)
    np.testing.assert_array_equal(np.rint(-a[:, 2] / LSB).astype(int), k % 500)
    np.testing.assert_allclose(a[:, 3], 256 * LSB)


def test_garbage_cut_lines_and_bad_checksums_are_counted_and_skipped():
    with scripted() as emu, SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        bad = bytearray(emu._line(2))
        bad[-3:-1] = b"00" if bad[-3:-1] != b"00" else b"01"
        for chunk in [
            emu._line(0),
            b"\x00\xff\xfe garbage \x07\r\n",
            b"$A,1,10" + emu._line(1),  # a line cut short, then a good one
            bytes(bad),  # sample 2 corrupted: skipped, and a gap in the counter
        ]:
            emu.send(chunk)
        a = [read_n(acc, 2)]
        emu.send(b"X" * 300)  # noise with no newline ...
        assert acc.read(timeout_s=0.05).shape == (0, 4)
        for chunk in [
            emu._line(3),  # ... then a good line
            frame_line("A,4,4000,1,2"),  # too few fields
            frame_line("A,70000,4000,1,2,3"),  # counter out of range
            frame_line("Q,1,2"),  # unknown line type
            emu._line(4).replace(b"\n", b"\r\n"),  # CRLF is fine
        ]:
            emu.send(chunk)
        a = np.vstack([*a, read_n(acc, 2)])
        exc = read_until_error(acc)  # and nothing else came out
    assert emu.port in str(exc)
    np.testing.assert_allclose(a[:, 0], [0.0, 0.001, 0.003, 0.004])
    np.testing.assert_array_equal(np.rint(a[:, 1] / LSB), [0, 1, 3, 4])
    st = acc.stats
    assert st.samples == 4 and st.bad_checksum == 1 and st.dropped == 1
    assert st.overlong == 1  # 300 bytes without a newline: dropped
    # garbage, the cut fragment, too few fields, counter range, unknown type
    assert st.malformed == 5


def test_dropped_samples_are_counted_from_the_counter():
    with scripted() as emu, SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(3):
            emu.send_sample()
        emu.skip(5)  # the device's FIFO overran: samples 3..7 never sent
        for _ in range(2):
            emu.send_sample()
        a = read_n(acc, 5)
    assert acc.stats.dropped == 5 and acc.stats.bad_lines == 0
    np.testing.assert_allclose(a[:, 0], [0, 0.001, 0.002, 0.008, 0.009])


def test_counter_and_clock_wraps_are_not_gaps():
    with scripted(counter0=65533, start_us=2**32 - 2500) as emu, \
            SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(6):
            emu.send_sample()  # n 65533 .. 65535, 0 .. 2; t_us wraps after sample 2
        a = read_n(acc, 6)
    assert acc.stats.dropped == 0 and acc.stats.device_resets == 0
    np.testing.assert_allclose(a[:, 0], np.arange(6) * 1e-3)


def test_a_device_reset_keeps_time_going_and_is_not_a_gap():
    with scripted() as emu, SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(50):
            emu.send_sample()
        emu.restart()  # hello, then counter 0 and clock 0 again
        for _ in range(3):
            emu.send_sample()
        a = read_n(acc, 53)
    assert acc.stats.device_resets == 1 and acc.stats.dropped == 0
    np.testing.assert_allclose(a[:, 0], np.arange(53) * 1e-3)


def test_a_reset_after_35_min_of_uptime_is_not_a_wrap():
    # The device ran 40 min (its microsecond count is past 2^31), then restarted: its
    # count falls by more than 2^31, as a wrap's does, but it is a restart (hello line).
    with scripted(start_us=40 * 60 * 10**6) as emu, \
            SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(50):
            emu.send_sample()
        emu.restart()
        for _ in range(3):
            emu.send_sample()
        a = read_n(acc, 53)
    assert acc.stats.device_resets == 1 and acc.stats.dropped == 0
    np.testing.assert_allclose(a[:, 0], np.arange(53) * 1e-3)


def test_a_restart_whose_hello_was_lost_is_not_a_wrap():
    # The same restart with its hello line lost on the link: the count falls from 50 min
    # of uptime to 0.4 s, a 'wrap' that would skip 21.6 min. Only a step of at most
    # max_gap_s across 2^32 is a wrap; a wrap with samples lost on it still is one.
    clock = DeviceClock(1e6)
    t = [clock.seconds(v, 1000) for v in (3_000_000_000, 3_000_001_000, 400_000, 401_000)]
    np.testing.assert_allclose(t, [0, 0.001, 0.002, 0.003])
    assert clock.resets == 1
    clock = DeviceClock(1e6)
    t = [clock.seconds(v, 1000) for v in (2**32 - 2000, 2**32 - 1000, 4000)]  # 4 lost
    np.testing.assert_allclose(t, [0, 0.001, 0.006])
    assert clock.resets == 0
    ms = DeviceClock(1000.0)  # the sensor board's milliseconds, 100 Hz
    np.testing.assert_allclose([ms.seconds(v, 10) for v in (2**32 - 10, 0, 2**31, 10)],
                               [0, 0.01, 0.01 + 2**31 / 1000, 0.01 + 2**31 / 1000 + 0.01])
    assert ms.resets == 1  # 2^31 -> 10 ms is a restart, not a wrap 24.9 days long


def test_a_device_that_dies_during_connect_leaves_the_port_closed():
    # The device goes away as the reader asks for its hello (the cable pulled then): the
    # reader's port must not stay open behind the error.
    opened = []

    def serial_factory(*args, **kw):
        import serial

        opened.append(serial.Serial(*args, **kw))
        return opened[-1]

    class DiesOnHello(AccelEmulator):
        def _on_command(self, cmd: bytes) -> None:
            if cmd == b"?":
                with self._lock:  # unplug() would join this very thread
                    self._unplugged = True
                    os.close(self._master)

    emu = DiesOnHello(counting, hello_on_start=False).start(streaming=False)
    try:
        acc = SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S,
                                  serial_factory=serial_factory)
        with pytest.raises(AccelError, match="accelerometer disconnected") as ei:
            acc.connect()
    finally:
        emu.stop()
    assert emu.port in str(ei.value)
    assert len(opened) == 1 and not opened[0].is_open


def test_saturated_counts_are_counted():
    with AccelEmulator(lambda k: (20 * G_M_S2 if k % 2 else 0.0, 0.0, G_M_S2),
                       range_g=16).start(streaming=False) as emu, \
            SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(10):
            emu.send_sample()
        a = read_n(acc, 10)
    assert acc.stats.saturated == 5
    assert np.max(a[:, 1]) == pytest.approx(16 * G_M_S2, rel=1e-3)  # clipped by the part


def test_a_stalled_device_is_an_error_naming_the_port():
    with AccelEmulator(counting).start() as emu, \
            SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        read_n(acc, 10)
        emu.pause()
        exc = read_until_error(acc)
        assert emu.port in str(exc) and "no valid samples" in str(exc)
        acc.timeout_s = DATA_TIMEOUT_S
        emu.resume()  # and it recovers when the device streams again
        assert len(read_n(acc, 5)) >= 5


def test_a_stream_of_garbage_is_an_error_not_a_hang():
    with scripted() as emu, SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        for _ in range(30):
            emu.send(b"#$%&garbage,1,2,3\n")
        exc = read_until_error(acc)
    assert emu.port in str(exc) and "30 bad lines" in str(exc)


def test_an_unplugged_device_is_an_error_naming_the_port():
    emu = AccelEmulator(counting).start()
    try:
        acc = SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S)
        acc.connect()
        read_n(acc, 10)
        emu.unplug()
        exc = read_until_error(acc)
        assert emu.port in str(exc) and "disconnected" in str(exc)
        acc.disconnect()
        acc.disconnect()
    finally:
        emu.stop()


def test_the_sensor_board_on_the_port_is_not_taken_for_the_accelerometer():
    with BoardEmulator(rate_hz=200).start() as board:
        acc = SerialAccelerometer(board.port, timeout_s=ERROR_TIMEOUT_S)
        with pytest.raises(AccelError, match="no hello line from the accelerometer") as ei:
            acc.connect()
    assert board.port in str(ei.value) and "FYDPAD-BOARD answered: wrong port?" in str(ei.value)
    assert acc.stats.malformed > 0 and acc.stats.samples == 0


def test_a_silent_device_at_connect_is_an_error_naming_the_port():
    with AccelEmulator(counting, hello_on_start=False).start(streaming=False) as emu:
        emu._on_command = lambda cmd: None  # firmware that never answers '?'
        acc = SerialAccelerometer(emu.port, timeout_s=ERROR_TIMEOUT_S)
        with pytest.raises(AccelError, match="no hello line") as ei:
            acc.connect()
    assert emu.port in str(ei.value) and "FYDPAD-ACCEL firmware at 921600 baud" in str(ei.value)


def test_a_missing_port_is_an_error_naming_it():
    with pytest.raises(AccelError, match="/dev/ttyFYDPAD-missing: cannot open"):
        SerialAccelerometer("/dev/ttyFYDPAD-missing").connect()
    acc = SerialAccelerometer("/dev/ttyFYDPAD-missing")
    with pytest.raises(AccelError, match="read before connect"):
        acc.read()


def test_serial_specs():
    with scripted() as emu:
        acc = open_accelerometer(f"serial:{emu.port}", timeout_s=DATA_TIMEOUT_S)
        assert isinstance(acc, SerialAccelerometer)
        assert (acc.port, acc.baud) == (emu.port, DEFAULT_BAUD) and DEFAULT_BAUD == 921600
        with acc:
            emu.send_sample()
            assert read_n(acc, 1).shape == (1, 4)
    assert open_accelerometer("serial:/dev/ttyUSB0@2000000").baud == 2_000_000
    with pytest.raises(AccelError, match=r"accelerometer 'serial:/dev/x@fast'.*baud"):
        open_accelerometer("serial:/dev/x@fast")
    with pytest.raises(AccelError, match="expected serial:PORT"):
        open_accelerometer("serial:")


def test_line_format_round_trip():
    line = accel_data_line(65535 + 3, 2**32 + 7, (-32768, 0, 32767))
    assert line.startswith(b"$A,2,7,-32768,0,32767*") and line.endswith(b"\n")
    p = parse_accel_line(line[:-1])
    assert (p.n, p.t_us, p.counts) == (2, 7, (-32768, 0, 32767))
    info = parse_accel_line(accel_hello_line(3200, 3.9, 2, "ADXL355")[:-1])
    assert info.rate_hz == 3200 and info.lsb_m_s2 == pytest.approx(3.9e-6 * G_M_S2)


def test_the_documented_example_lines_parse():
    doc = Path(__file__).resolve().parents[2] / "docs" / "accel_protocol.md"
    examples = [ln for ln in doc.read_text().splitlines()
                if re.fullmatch(r"\$[AH],[^<>]*\*[0-9A-F]{2}", ln)]
    assert len(examples) == 2
    parsed = [parse_accel_line(ln.encode()) for ln in examples]
    assert parsed[0].counts == (12, -5, 256) and parsed[1].part == "ADXL345"


def test_a_clocked_part_never_sends_a_sample_before_its_time():
    # A sample sent before its time on the device's clock gives an older value a later
    # time: a catch-up running 1-2 samples ahead (1.2-1.4 ms early) holds the device-path
    # identification's coherence at 0.02-0.3.
    sent: list[tuple[int, float]] = []
    emu = AccelEmulator(clocked=True)

    def recording(k: int) -> tuple[float, float, float]:
        sent.append((k, time.monotonic()))
        return counting(k)

    emu.signal_fn = recording
    with emu.start(), SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        read_n(acc, 300)
    early_s = [emu.sample_time_s(k) - t for k, t in sent]
    assert max(early_s) <= 0.0, f"{sum(e > 0 for e in early_s)} samples sent early"


@pytest.mark.parametrize("fifo_depth", [1000, 32])
def test_a_starved_clocked_part_drains_its_fifo_and_loses_only_the_overflow(fifo_depth):
    """The emulator's thread held off for 80 ms (a starved microcontroller): with a FIFO
    deeper than that (1000 samples: slack for a loaded machine) nothing is lost; with the
    ADXL345's 32 the samples due while it was held, less the 32, are one counted gap."""
    emu = AccelEmulator(counting, clocked=True, fifo_depth=fifo_depth)
    with emu.start(), SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        before = read_n(acc, 50)
        with emu._lock:  # the emulator's thread cannot send
            t0 = time.monotonic()
            time.sleep(0.08)
            held_ms = 1000 * (time.monotonic() - t0)
        a = np.vstack([before, read_n(acc, 150)])
    gaps = np.rint(np.diff(a[:, 0]) * 1000).astype(int) - 1
    assert acc.stats.dropped == gaps.sum()
    if fifo_depth > 500:
        assert gaps.max() == 0, gaps.max()
    else:  # at least what the hold alone made overflow; the thread's wake-up may add
        assert held_ms - 32 - 2 <= gaps.max() <= held_ms - 32 + 200, (gaps.max(), held_ms)


def test_a_clocked_part_restarts_its_clock_with_its_counter():
    # After a reset sample 0 is due at once, not the samples due since the first start
    # (which came as a 32-sample burst from a counter far from 0: a gap, not a reset).
    emu = AccelEmulator(counting, clocked=True)
    with emu.start(), SerialAccelerometer(emu.port, timeout_s=DATA_TIMEOUT_S) as acc:
        read_n(acc, 100)
        emu.restart()
        after = read_n(acc, 100)
    k = np.rint(after[:, 1] / LSB).astype(int)  # the sample index, from the data itself
    # (a read may still return the tail of the old stream before the reset)
    assert 0 in k and np.all(np.diff(k[list(k).index(0):]) == 1), k[:40]
    assert acc.stats.device_resets == 1 and acc.stats.dropped == 0, acc.stats
