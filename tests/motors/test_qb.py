"""The QB board backend over a real pseudo-terminal against the emulated board:
activation, inputs, measurements, the control mode, and every failure with a deadline
(no reply, bad checksums, stray bytes, a missing port)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from fydpad.motors import qb_protocol as qp
from fydpad.motors.base import MotorError, MotorPair
from fydpad.motors.drive import MotorDrive
from fydpad.motors.qb import QbBoardConfig, QbMotors, QbTimeoutError
from fydpad.motors.qb_emulator import QbEmulator

#: A hang guard, never a speed: the emulator is a thread of this process, and on a
#: loaded machine it may answer a set-up command (or the first read, after 800 queued
#: SET_INPUTS frames) seconds late. The test of the deadline passes a short one.
SETUP_TIMEOUT_S = 10.0
#: A late tick reply is reused (up to max_missed_replies): per-tick reads stay short.
TICK_TIMEOUT_S = 0.05


@pytest.fixture
def emu():
    with QbEmulator(device_id=3) as e:
        yield e


def board(emu, **kw) -> QbMotors:
    # The watchdog off unless a test arms it: this test thread, not paced and not
    # real-time, may pause past its 20 ms on a loaded machine, and the board would stop.
    kw.setdefault("watchdog_cs", 0)
    kw.setdefault("timeout_s", SETUP_TIMEOUT_S)
    kw.setdefault("tick_timeout_s", TICK_TIMEOUT_S)
    cfg = QbBoardConfig(port=emu.port, device_id=3, **kw)
    return QbMotors(cfg)


def test_activate_sets_pwm_mode_and_powers_motors(emu):
    m = board(emu)
    assert isinstance(m, MotorPair)
    with m:
        assert emu.activation == qp.ACTIVATE_BOTH
        assert emu.control_mode == qp.CONTROL_PWM
        assert m.get_activate() == qp.ACTIVATE_BOTH
        assert emu.received[:2] == [qp.CMD_PING, qp.CMD_GET_PARAM_LIST]
    # Leaving the context: zero duty, then power off.
    assert _wait(lambda: emu.activation == 0)
    assert emu.inputs == (0, 0)


def test_pwm_inputs_and_measurements_round_trip(emu):
    with board(emu) as m:
        m.set_pwm(0.25, -1.7)  # clipped to full scale
        assert _wait(lambda: emu.inputs == (25, -100))
        # The plant behind the emulator winds motor 0 up under positive duty.
        for _ in range(300):
            m.set_pwm(0.4, 0.4)
        th = m.read_positions_rad()
        plant = emu.plant
        assert th[0] == pytest.approx(plant.theta_rad[0], abs=2 * math.pi / 65536 * 2)
        assert th[0] > 0.2
        assert m.stats() == {"timeouts": 0, "checksum_errors": 0, "garbage_bytes": 0}


def test_position_mode_sends_counts_and_refuses_pwm(emu):
    with board(emu, control_mode="position") as m:
        assert emu.control_mode == qp.CONTROL_ANGLE
        m.set_positions_rad(0.5, 0.25)
        assert _wait(lambda: emu.inputs == (round(0.5 / (2 * math.pi) * 65536),
                                            round(0.25 / (2 * math.pi) * 65536)))
        with pytest.raises(MotorError, match="control_mode = 'pwm'"):
            m.set_pwm(0.1, 0.1)
        # The board's own loop moves the rollers towards the reference.
        for _ in range(800):
            m.set_positions_rad(0.6, 0.6)
        th = m.read_positions_rad()
        assert th[0] == pytest.approx(0.6, abs=0.03)


def test_full_loop_on_the_board_holds_a_position(emu):
    with board(emu) as m:
        drive = MotorDrive(m)
        drive.start()
        drive.set_theta_rad(0.7)
        n0 = emu.received.count(qp.CMD_SET_INPUTS)
        for _ in range(1500):
            drive.tick(0.0)
        # The emulator (a thread here) may be behind a loaded machine: the plant as of
        # every duty sent, not as of those it has read so far.
        assert _wait(lambda: emu.received.count(qp.CMD_SET_INPUTS) >= n0 + 1500)
        assert emu.plant.theta_rad[0] == pytest.approx(0.7, abs=0.01)
        drive.safe_stop()
        assert _wait(lambda: emu.activation == 0)


def test_silent_board_times_out_naming_the_port(emu):
    emu.mute = True
    m = board(emu, timeout_s=0.2)
    t0 = time.monotonic()
    with pytest.raises(QbTimeoutError, match=rf"{emu.port}.*PING.*device 3.*200 ms"):
        m.activate()
    assert time.monotonic() - t0 < 5.0  # a deadline, never a hang
    m.close()


@pytest.mark.parametrize("pipelined", [False, True])
def test_missed_tick_replies_reuse_last_reading_then_fail(emu, pipelined):
    with board(emu, pipelined=pipelined) as m:
        first = m.read_positions_rad()
        assert m.read_positions_rad() == first  # (pipelined: the pipeline is primed)
        if pipelined:  # the reply to the request in flight is back before the board mutes
            assert _wait(lambda: m._ser.in_waiting >= 10)
        emu.mute = True
        # Pipelined, the reply to the request sent before the board fell silent is
        # still taken; then up to max_missed_replies misses reuse the last reading.
        for _ in range(int(pipelined) + m.config.max_missed_replies):
            assert m.read_positions_rad() == first
        with pytest.raises(QbTimeoutError, match="GET_MEASUREMENTS"):
            m.read_positions_rad()
        emu.mute = False
        # Recovers once the board answers (pipelined: from the next request on).
        for attempt in range(3):
            try:
                assert m.read_positions_rad() == first
                break
            except QbTimeoutError:
                assert pipelined and attempt == 0
        assert m.stats()["timeouts"] >= m.config.max_missed_replies + 1


def test_pipelined_reads_follow_the_plant(emu):
    with board(emu, pipelined=True) as m:
        seen = []
        for _ in range(400):
            th = m.read_positions_rad()
            m.set_pwm(0.4, 0.4)
            seen.append(th[0])
        # The readings follow the plant winding up (a late reply reuses the last one).
        assert np.all(np.diff(seen[50:]) >= 0)
        # With no more duties the plant stands still (the emulator steps it per
        # SET_INPUTS): the next fresh reading is where it is, to an encoder count.
        for _ in range(1000):
            before = m.reused_readings
            th = m.read_positions_rad()
            if m.reused_readings == before and m._in_flight <= 1:
                th = m.read_positions_rad()  # the reply to a request sent after the last duty
                if m.reused_readings == before:
                    break
        assert abs(th[0] - emu.plant.theta_rad[0]) <= 2 * math.pi / 65536
        # 400 duties of 0.4 wound it up (the emulator steps the plant per SET_INPUTS,
        # so this is a count of frames, not of seconds).
        assert th[0] > 0.2


def test_watchdog_is_armed_on_activation_at_the_shortest_period_by_default(emu):
    cfg = QbBoardConfig(port=emu.port, device_id=3)
    assert cfg.watchdog_cs == 2
    with QbMotors(cfg):
        assert _wait(lambda: emu.watchdog == 1)  # commSetWatchDog(2 cs) sends 2 / 2
    with board(emu, watchdog_cs=100):
        assert _wait(lambda: emu.watchdog == 50)


@pytest.mark.parametrize("cs", [1, 501, -2])
def test_a_watchdog_the_firmware_cannot_count_is_refused(emu, cs):
    with pytest.raises(MotorError, match=r"watchdog_cs must be 0 .off. or 2-500"):
        board(emu, watchdog_cs=cs)


def test_the_board_stops_by_itself_when_commands_stop(emu):
    """A host that stops sending (hung, killed) leaves the board at rest: the watchdog
    deactivates it at its deadline, 20 ms after the last frame, by the board's clock."""
    m = board(emu, watchdog_cs=2)
    m.activate()
    for _ in range(50):
        m.set_pwm(0.4, -0.4)
        m.read_positions_rad()
    assert _wait(lambda: emu.received.count(qp.CMD_SET_INPUTS) >= 51)
    # Nothing more is sent: no deactivate, no close.
    assert _wait(emu.at_rest, timeout_s=5.0)
    # At rest by the period after the host's last frame, on the board's clock (a stall
    # of this unpaced test thread may have stopped it earlier, and it stayed stopped).
    stops = emu.watchdog_stops
    assert stops and stops[-1][1] <= emu.last_frame_s + 0.02 + 1e-9
    assert all(stop - last == pytest.approx(0.02) for last, stop in stops)
    assert emu.activation == 0 and not emu.plant.powered
    m.close()


def test_late_replies_reuse_the_last_reading_and_never_hold_the_read(emu):
    """Replies held back by the board: every read gives up after its tick_timeout_s
    (not the set-up timeout_s), reusing the last reading as it was; once the replies
    come, a read takes the newest of them."""
    m = board(emu, max_missed_replies=10_000, tick_timeout_s=0.005)
    m.activate()
    m.set_pwm(0.3, 0.3)
    m.read_positions_rad()  # waits the set-up timeout; sends the next request
    # That request answered at once, hold every later reply until the test sends them.
    assert _wait(lambda: m._ser.in_waiting > 0)
    emu.reply_delay_s = 3600.0
    reused0 = m.reused_readings
    first = m.read_positions_rad()  # the reply already there: fresh
    assert m.reused_readings == reused0
    n_late = 20
    t0 = time.monotonic()
    for _ in range(n_late):
        m.set_pwm(0.3, 0.3)  # the plant moves on each SET_INPUTS
        assert m.read_positions_rad() == first  # the last reading, as it was
    # A hang guard, not a speed: 20 reads that each waited the 10 s set-up timeout
    # instead of the 5 ms tick timeout would take 200 s.
    assert time.monotonic() - t0 < SETUP_TIMEOUT_S
    assert m.reused_readings - reused0 == n_late
    # Every read sent its request: none waited for a reply before sending the next.
    assert _wait(lambda: emu.received.count(qp.CMD_GET_MEASUREMENTS) == n_late + 3)
    emu.send_delayed_replies()
    deadline = time.monotonic() + SETUP_TIMEOUT_S  # a hang guard
    while (th := m.read_positions_rad()) == first:
        assert time.monotonic() < deadline, "the late replies were never taken"
    # The newest reply: the plant wound up under the duty since the first reading.
    assert th[0] > first[0]
    m.deactivate()
    m.close()


def test_bad_checksum_reply_is_rejected_and_reported(emu):
    with board(emu) as m:
        emu.corrupt_replies = 1
        with pytest.raises(QbTimeoutError, match=r"1 reply.*bad checksum"):
            m.ping()
        m.ping()  # the next, intact reply is accepted
        assert m.stats()["checksum_errors"] == 1


def test_garbage_before_replies_is_skipped(emu):
    with board(emu) as m:
        emu.garbage_before_reply = b"\x00\xff noise ::\x01\x05junk::"
        m.ping()
        th = m.read_positions_rad()
        assert all(math.isfinite(v) for v in th)
        assert m.stats()["garbage_bytes"] > 0


def test_host_frames_with_bad_checksum_are_ignored_by_board(emu):
    with board(emu) as m:
        frame = bytearray(qp.command(3, qp.CMD_SET_INPUTS, qp.int16s(50, 50)))
        frame[-1] ^= 1
        m._ser.write(bytes(frame))
        m.set_pwm(0.1, 0.1)
        assert _wait(lambda: emu.inputs == (10, 10))
        assert emu.bad_frames == 1


def test_other_board_id_gets_no_reply(emu):
    m = QbMotors(QbBoardConfig(port=emu.port, device_id=9, timeout_s=0.1))
    with pytest.raises(QbTimeoutError, match="device 9"):
        m.ping()
    m.close()


def test_missing_port_is_a_clear_error(tmp_path):
    with pytest.raises(MotorError, match=r"cannot open .*nope"):
        QbMotors(QbBoardConfig(port=str(tmp_path / "nope")))


def test_refused_control_mode_is_reported(emu):
    m = board(emu, control_mode_param_index=42)
    with pytest.raises(MotorError, match="refused"):
        m.activate()
    m.close()


def _wait(cond, timeout_s=SETUP_TIMEOUT_S) -> bool:
    """The emulator handles bytes on its own thread: wait (bounded) for it to catch up."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.002)
    return cond()
