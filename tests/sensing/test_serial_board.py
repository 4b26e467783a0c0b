"""The real pyserial reader against the emulated board over a pseudo-terminal: good data,
garbage, partial lines, bad checksums, a silent board, an unplugged one, a missing port.

Every read has the reader's own timeout, so nothing can hang: 0.3 s where a test waits
for the error, 5 s elsewhere (generous, so a starved emulator thread on a busy
machine does not fail a test that expects data).
"""

from __future__ import annotations

import itertools

import pytest

from vision.board_emulator import BoardEmulator
from vision.config import ForceConfig, IRConfig
from vision.sensors import (
    ForceSource,
    IRSource,
    SensorError,
    SerialBoard,
    data_line,
    frame_line,
    hello_line,
    parse_line,
)

TIMEOUT_S = 0.3  # where the error is the expected outcome
DATA_TIMEOUT_S = 5.0  # where data is
FORCE = ForceConfig(offset_counts=-500.0, gain_n_per_count=1e-6)


def ramp(k: int):
    """Sample k: three related ADC values and a force count, so every field is checked."""
    v = 200 + k % 600
    return (v, v + 7, 1023 - v), 1000 * v


def open_board(emu: BoardEmulator) -> SerialBoard:
    return SerialBoard(emu.port, ir_config=IRConfig(rate_hz=emu.rate_hz), force_config=FORCE,
                       timeout_s=DATA_TIMEOUT_S)


def read_until_error(board: SerialBoard, read, limit: int = 100_000) -> SensorError:
    """Read until the fault is reported (with the short timeout), then restore it."""
    board.timeout_s = TIMEOUT_S
    try:
        for _ in range(limit):
            try:
                read()
            except SensorError as exc:
                return exc
        raise AssertionError("the reader never reported the fault")
    finally:
        board.timeout_s = DATA_TIMEOUT_S


def test_good_stream_converts_every_field():
    with BoardEmulator(ramp, rate_hz=500).start() as emu, open_board(emu) as board:
        assert isinstance(board.ir, IRSource) and isinstance(board.force, ForceSource)
        ir = [board.ir.read() for _ in range(100)]
        force = [board.force.read() for _ in range(100)]
        assert board.info is not None and board.info.adc_bits == 10 and board.info.vref_v == 5.0
        assert b"?" in emu.commands  # the reader asked for the hello line
    lsb = 5.0 / 1024
    for s in ir:
        v0 = round(s.volts[0] / lsb)
        assert s.volts == pytest.approx((v0 * lsb, (v0 + 7) * lsb, (1023 - v0) * lsb))
        assert s.valid == tuple(0.42 <= v <= 2.75 for v in s.volts)
    steps = [b.t_s - a.t_s for a, b in itertools.pairwise(ir)]
    # Board clock: 2 ms per sample (a multiple if bytes were dropped on a busy machine).
    assert all(st > 0 and abs(st / 0.002 - round(st / 0.002)) < 1e-6 for st in steps)
    by_t = {round(s.t_s, 6): s for s in ir}
    for f in force:
        assert f.force_n == pytest.approx(1e-6 * (f.raw + 500.0))
        assert not f.saturated
        if round(f.t_s, 6) in by_t:
            assert f.raw == 1000 * round(by_t[round(f.t_s, 6)].volts[0] / lsb)


def test_garbage_partial_lines_and_bad_checksums_are_counted_and_skipped():
    emu = BoardEmulator(ramp, rate_hz=100).start(streaming=False)
    with emu, open_board(emu) as board:
        bad_checksum = bytearray(data_line(20, ramp(2)[0], ramp(2)[1]))
        bad_checksum[-3:-1] = b"00" if bad_checksum[-3:-1] != b"00" else b"01"
        script = [
            data_line(0, *ramp(0)),
            b"\x00\xff\xfe garbage \x07\r\n",
            b"$D,10,5" + data_line(10, *ramp(1)),  # a line cut short, then a good one
            bytes(bad_checksum),
            b"X" * 500 + data_line(30, *ramp(3)),  # noise with no newline, then good
            frame_line("D,40,2000,5,5,0"),  # ADC value out of range for 10 bits
            frame_line("Q,1,2"),  # unknown line type
            data_line(40, *ramp(4)),
            data_line(50, *ramp(5)).replace(b"\n", b"\r\n"),  # CRLF is fine
        ]
        for chunk in script:
            emu.send(chunk)
        got = [board.ir.read() for _ in range(5)]
        assert [round(s.t_s, 3) for s in got] == [0.0, 0.01, 0.03, 0.04, 0.05]
        assert [round(s.volts[0] * 1024 / 5) for s in got] == [200, 201, 203, 204, 205]
        # Nothing else came out: the next read times out.
        exc = read_until_error(board, board.ir.read)
        assert emu.port in str(exc)
        st = board.stats
        assert st.lines_ok == 5 and st.bad_checksum == 1
        # garbage, the cut line, the noise before line 3, the ADC range, the unknown type
        assert st.malformed + st.overlong >= 5


def test_a_board_that_stops_sending_is_an_error_naming_the_port():
    with BoardEmulator(ramp, rate_hz=500).start() as emu, open_board(emu) as board:
        board.ir.read()
        emu.pause()
        exc = read_until_error(board, board.ir.read)
        assert emu.port in str(exc) and "no valid data" in str(exc)
        emu.resume()  # and it recovers when the board comes back
        assert board.ir.read() is not None


def test_a_stream_of_garbage_is_an_error_not_a_hang():
    emu = BoardEmulator(ramp).start(streaming=False)
    with emu, open_board(emu) as board:
        for _ in range(40):
            emu.send(b"#$%&garbage,1,2,3\n")
        exc = read_until_error(board, board.force.read)
        assert emu.port in str(exc) and "40 bad lines" in str(exc)


def test_an_unplugged_board_is_an_error_naming_the_port():
    emu = BoardEmulator(ramp, rate_hz=500).start()
    try:
        board = open_board(emu)
        board.ir.read()
        emu.unplug()
        exc = read_until_error(board, board.ir.read)
        assert emu.port in str(exc) and "disconnected" in str(exc)
        board.close()
    finally:
        emu.stop()


def test_a_missing_port_is_an_error_naming_it():
    with pytest.raises(SensorError, match="/dev/ttyFYDPAD-missing"):
        SerialBoard("/dev/ttyFYDPAD-missing", timeout_s=TIMEOUT_S)


def test_board_clock_wraps_and_resets_keep_time_going_forward():
    emu = BoardEmulator(ramp, rate_hz=100, start_ms=2**32 - 25).start(streaming=False)
    with emu, open_board(emu) as board:
        for _ in range(6):
            emu.send_sample()  # t_ms 4294967271 ... wraps ... 25
        t = [board.ir.read().t_s for _ in range(6)]
        assert t == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
        emu.send(hello_line(100, 10, 5000))  # the board restarted: its clock too
        emu.send(data_line(0, *ramp(0)))
        emu.send(data_line(10, *ramp(1)))
        t2 = [board.ir.read().t_s for _ in range(2)]
        assert t2 == pytest.approx([0.06, 0.07])
        assert board.stats.board_resets == 1 and board.stats.hello >= 1


def test_line_format_round_trip():
    line = data_line(1234, (1, 2, 1023), -8388608)
    assert line.startswith(b"$D,1234,1,2,1023,-8388608*") and line.endswith(b"\n")
    parsed = parse_line(line[:-1])
    assert parsed.t_ms == 1234 and parsed.v_raw == (1, 2, 1023)
    assert parsed.force_raw == -8388608
    assert parse_line(data_line(5, (1, 2, 3), None)[:-1]).force_raw is None


def test_a_board_without_load_cell_says_so():
    emu = BoardEmulator(lambda k: ((268, 268, 268), None), rate_hz=500).start()
    with emu, open_board(emu) as board:
        assert board.ir.read().valid == (True, True, True)
        exc = read_until_error(board, board.force.read)
        assert emu.port in str(exc) and "no force data" in str(exc)


def test_ir_and_force_loops_read_their_views_from_two_threads():
    import threading

    results: dict[str, list] = {}

    def loop(name, view):
        results[name] = [view.read() for _ in range(200)]

    with BoardEmulator(ramp, rate_hz=1000).start() as emu, open_board(emu) as board:
        threads = [threading.Thread(target=loop, args=("ir", board.ir)),
                   threading.Thread(target=loop, args=("force", board.force))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=30)
        assert not any(t.is_alive() for t in threads)
    for name in ("ir", "force"):
        t = [s.t_s for s in results[name]]
        assert len(t) == 200 and all(b > a for a, b in itertools.pairwise(t))


def test_the_documented_example_lines_parse():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "sensor_board_protocol.md")
    import re

    examples = [ln for ln in doc.read_text().splitlines()
                if re.fullmatch(r"\$[DH],[^<>]*\*[0-9A-F]{2}", ln)]
    assert len(examples) == 2
    for ln in examples:
        parse_line(ln.encode())


def test_one_loop_reads_ir_and_force_of_the_same_line():
    emu = BoardEmulator(ramp, rate_hz=100).start(streaming=False)
    with emu, open_board(emu) as board:
        emu.send(data_line(0, *ramp(0)))
        emu.send(data_line(10, (300, 300, 300), None))  # this line has no force
        emu.send(data_line(20, *ramp(2)))
        pairs = [board.read() for _ in range(3)]
    assert [round(ir.t_s, 3) for ir, _ in pairs] == [0.0, 0.01, 0.02]
    assert pairs[1][1] is None
    assert pairs[0][1].raw == 200_000 and pairs[2][1].raw == 202_000
    assert pairs[2][1].t_s == pairs[2][0].t_s
