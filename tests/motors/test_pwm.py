"""Eq. (3) composition: sums, headroom, clip counts, gain, vibration off."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fydpad.motors.control import PositionLoop
from fydpad.motors.pwm import PwmComposer, PwmConfig


def test_eq3_is_the_sum_per_motor_with_vibration_sign():
    c = PwmComposer(PwmConfig(duty_max=1.0, vibration_headroom=0.3, vibration_duty_per_unit=1.0),
                    vibration_sign=(1, -1))
    d = c.compose(0.2, 0.25, 0.1)
    assert d == pytest.approx([0.3, 0.15])
    assert c.position_clips == c.vibration_clips == 0 and c.ticks == 1


def test_headroom_clips_each_part_and_counts():
    c = PwmComposer(PwmConfig(duty_max=1.0, vibration_headroom=0.3, vibration_duty_per_unit=1.0),
                    vibration_sign=(1, 1))
    d = c.compose(0.9, -0.95, 0.5)
    # Position limited to 0.7, vibration to 0.3: the sum reaches 1.0 at most.
    assert d == pytest.approx([1.0, -0.4])
    assert c.position_clips == 2 and c.vibration_clips == 1
    s = c.stats()
    assert s["position_clips"] == 2 and s["vibration_clip_pct"] == pytest.approx(100.0)


@given(p0=st.floats(-5, 5), p1=st.floats(-5, 5), v=st.floats(-5, 5),
       gain=st.floats(0, 4), headroom=st.floats(0.0, 0.9))
def test_sum_never_exceeds_full_scale_and_position_keeps_its_share(p0, p1, v, gain, headroom):
    c = PwmComposer(PwmConfig(duty_max=1.0, vibration_headroom=headroom,
                                  vibration_duty_per_unit=1.0))
    c.gain = gain
    d = c.compose(p0, p1, v)
    assert abs(d[0]) <= 1.0 + 1e-12 and abs(d[1]) <= 1.0 + 1e-12
    # Whatever the vibration does, the position part it is added to is the loop's own
    # output (clipped only to its share): the vibration's contribution is bounded.
    plim = 1.0 - headroom
    assert abs(d[0] - max(-plim, min(plim, p0))) <= headroom + 1e-12


def test_gain_scales_and_disable_removes_vibration():
    c = PwmComposer(PwmConfig(vibration_headroom=0.5, vibration_duty_per_unit=1.0),
                    vibration_sign=(1, -1))
    c.gain = 2.0
    assert c.compose(0.0, 0.0, 0.1) == pytest.approx([0.2, -0.2])
    c.vibration_enabled = False
    assert c.compose(0.1, 0.1, 0.4) == pytest.approx([0.1, 0.1])


def test_duty_list_is_reused():
    c = PwmComposer(PwmConfig(vibration_duty_per_unit=1.0))
    a = c.compose(0.1, 0.1, 0.0)
    b = c.compose(0.2, 0.2, 0.0)
    assert a is b is c.duty


def test_bad_config_rejected():
    with pytest.raises(ValueError):
        PwmConfig(duty_max=1.5)
    with pytest.raises(ValueError):
        PwmConfig(vibration_headroom=1.0)


def test_position_loop_pid_terms():
    loop = PositionLoop(kp=2.0, ki=10.0, kd=0.1, dt_s=0.001, output_limit=0.7)
    u = loop.update(0.1, 0.0, 0.0, 0.0)
    # First tick: no derivative yet; integral one step of the error.
    assert u[0] == pytest.approx(2.0 * 0.1 + 10.0 * 0.1 * 0.001)
    assert u[1] == 0.0
    # Measurement moves by 0.01 rad in one tick: derivative on measurement -0.1*10.
    u = loop.update(0.1, 0.0, 0.01, 0.0)
    assert u[0] == pytest.approx(2.0 * 0.09 + 10.0 * (0.1 + 0.09) * 0.001 - 0.1 * 10.0)


def test_position_loop_anti_windup():
    loop = PositionLoop(kp=10.0, ki=100.0, kd=0.0, dt_s=0.001, output_limit=0.7)
    for _ in range(1000):
        loop.update(1.0, 0.0, 0.0, 0.0)  # saturated all along
    # The integral did not grow while saturated: once the error reverses, the output
    # follows at once.
    u = loop.update(0.0, 0.0, 0.1, 0.0)
    assert u[0] < 0
