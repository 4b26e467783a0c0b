"""The IR sensors' own timing: each Sharp sensor measures every 16.5 ms and holds its
output in between; the board reads it at 100 Hz. Taken at the board's times the held
output lags the fabric (8 ms on average); the held repeats dropped and each new reading
placed at its measurement time, the lag goes, offline (``resample_distances_mm``) and
causally (``filter_distances_mm``, the stream's path)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vision.config import IRConfig
from vision.indentation import (
    DistanceFilterState,
    IndentationEstimator,
    filter_distances_mm,
    is_held,
    measurement_time_s,
    resample_distances_mm,
)
from vision.ir import SENSOR_PERIOD_S

SPEED_MM_S = 80.0  # the test pads' fastest taps


def _fabric_mm(t: np.ndarray) -> np.ndarray:
    """Distance above each sensor: down and back at up to 80 mm/s, 40 mm deep."""
    return 100.0 - 40.0 * np.sin(np.pi * t / 1.5) ** 2 * np.array([[1.0], [0.7], [0.5]]).T[0]


def _held_board_samples(seed: int, board_hz: float = 100.0, seconds: float = 3.0):
    """Board samples of three sensors that measure every ~16.5 ms (+-5 %, random phase)
    and hold, quantised to 0.05 mm: (t_board, distances[n, 3], true distances[n, 3])."""
    rng = np.random.default_rng(seed)
    t_b = np.arange(0.0, seconds, 1.0 / board_hz)
    held = np.empty((t_b.size, 3))
    for i in range(3):
        n = int(seconds / SENSOR_PERIOD_S) + 4
        t_m = np.cumsum(SENSOR_PERIOD_S * rng.uniform(0.95, 1.05, n)) \
            - rng.uniform(0, SENSOR_PERIOD_S) - SENSOR_PERIOD_S
        z_m = _fabric_mm(t_m[:, None].repeat(3, 1))[:, i]
        k = np.searchsorted(t_m, t_b, side="right") - 1
        held[:, i] = np.round(z_m[k] / 0.05) * 0.05
    return t_b, held


def test_a_held_reading_is_told_from_a_new_one():
    # Same reading within a period of the last new one: held. Later: measured again.
    assert is_held(95.0, 95.0, 0.010, 0.0, SENSOR_PERIOD_S)
    assert not is_held(95.0, 95.0, 0.020, 0.0, SENSOR_PERIOD_S)
    assert not is_held(94.9, 95.0, 0.010, 0.0, SENSOR_PERIOD_S)
    assert not is_held(95.0, math.nan, 0.010, 0.0, SENSOR_PERIOD_S)
    # A new reading seen at 20 ms, the board's previous sample at 10 ms: measured at 15 ms.
    assert measurement_time_s(0.020, 0.010, SENSOR_PERIOD_S) == pytest.approx(0.015)
    # A sensor faster than the board: within its own period before the sample.
    assert measurement_time_s(0.020, 0.0, 0.004) == pytest.approx(0.018)
    # Period 0: the board's sample is the measurement.
    assert measurement_time_s(0.020, 0.010, 0.0) == 0.020


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_offline_resampling_removes_the_held_outputs_lag(seed):
    t_b, d = _held_board_samples(seed)
    t_f = np.arange(0.2, 2.8, 1 / 30)  # frames
    truth = _fabric_mm(t_f[:, None].repeat(3, 1))
    fl = np.zeros(t_b.size, np.int64)
    naive, _ = resample_distances_mm(t_b, d, fl, t_f)
    timed, _ = resample_distances_mm(t_b, d, fl, t_f, sensor_period_s=(SENSOR_PERIOD_S,) * 3)
    # Going down (distance falling) the held output reads too far, coming up too near:
    # the lag shows as error correlated with the fabric's velocity.
    v = np.gradient(truth[:, 0], t_f)
    fast = np.abs(v) > 0.5 * SPEED_MM_S
    lag_naive = -np.mean((naive - truth)[fast, 0] / v[fast])
    lag_timed = -np.mean((timed - truth)[fast, 0] / v[fast])
    assert lag_naive > 0.006  # ~8 ms: half the sensor's period, plus interpolation
    assert abs(lag_timed) < 0.002
    assert np.sqrt(np.mean((timed - truth) ** 2)) < 0.6 * np.sqrt(np.mean((naive - truth) ** 2))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_causal_filter_removes_the_held_outputs_lag(seed):
    t_b, d = _held_board_samples(seed)
    fl = np.zeros(t_b.size, np.int64)
    errs = {}
    for period in (0.0, SENSOR_PERIOD_S):
        st = DistanceFilterState.initial()
        e, v = [], []
        j = 0
        for tq in np.arange(0.2, 2.8, 1 / 30):
            k = int(np.searchsorted(t_b, tq, side="right"))
            out, _, st = filter_distances_mm(st, t_b[j:k], d[j:k], fl[j:k], tq,
                                             sensor_period_s=(period,) * 3)
            j = k
            e.append(out[0] - _fabric_mm(np.array([tq] * 3))[0])
            v.append(-40.0 * np.pi / 1.5 * np.sin(2 * np.pi * tq / 1.5))
        e, v = np.array(e), np.array(v)
        fast = np.abs(v) > 0.5 * SPEED_MM_S
        errs[period] = (-np.mean(e[fast] / v[fast]), float(np.sqrt(np.mean(e**2))))
    assert errs[0.0][0] > 0.006  # the held output's lag, about 8 ms
    assert abs(errs[SENSOR_PERIOD_S][0]) < 0.002
    assert errs[SENSOR_PERIOD_S][1] < 0.6 * errs[0.0][1]


def test_the_filter_updates_its_state_in_place():
    """The per-frame path allocates no arrays: the state's buffers are updated and the
    distances come back in its ``out`` buffer."""
    t_b, d = _held_board_samples(4)
    fl = np.zeros(t_b.size, np.int64)
    st = DistanceFilterState.initial()
    buffers = [id(a) for a in (st.x, st.p, st.t_s, st.held_mm, st.new_t_s, st.out)]
    out, _, st2 = filter_distances_mm(st, t_b[:5], d[:5], fl[:5], t_b[4],
                                      sensor_period_s=(SENSOR_PERIOD_S,) * 3)
    assert st2 is st and out is st.out
    assert [id(a) for a in (st.x, st.p, st.t_s, st.held_mm, st.new_t_s, st.out)] == buffers
    assert np.all(np.isfinite(out))


def test_the_sensor_period_is_device_configuration():
    assert IRConfig().sensor_period_s == (SENSOR_PERIOD_S,) * 3
    est = IndentationEstimator.from_config(IRConfig(sensor_period_s=(0.0165, 0.02, 0.0)))
    assert est.sensor_period_s == (0.0165, 0.02, 0.0)
    with pytest.raises(ValueError, match="sensor_period_s"):
        IRConfig(sensor_period_s=(0.0165, -1.0, 0.0165))
    with pytest.raises(ValueError, match="sensor_period_s"):
        IRConfig(sensor_period_s=(0.0165, 0.0165))  # type: ignore[arg-type]
