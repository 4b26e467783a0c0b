import numpy as np
import pytest

from fydpad.accel.base import AccelError
from fydpad.accel.replay import ReplayAccelerometer


def _write(path, rows, header="t_s,ax_m_s2,ay_m_s2,az_m_s2"):
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows))
    return path


def test_replay_all_rows(tmp_path):
    t = np.arange(50) / 1000.0
    rows = [f"{a},{np.sin(a)},0.5,9.81" for a in t]
    with ReplayAccelerometer(_write(tmp_path / "a.csv", rows), speed=float("inf")) as acc:
        block = acc.read()
        assert acc.read().shape == (0, 4)
        assert acc.finished
    assert acc.rate_hz == pytest.approx(1000.0)
    np.testing.assert_allclose(block[:, 0], t)
    np.testing.assert_allclose(block[:, 1], np.sin(t))


@pytest.mark.parametrize("rows, header, match", [
    (["0,1,2,3", "0.001,1,x,3"], None, r"line 3: column 'ay_m_s2'"),
    (["0,1,2,3", "0.001,1,2"], None, r"line 3: expected 4 fields"),
    (["0,1,2,3", "0,1,2,3"], None, r"line 3: column 't_s' does not increase"),
    # A comment above the header and a blank line move the rows down: the real line.
    (["0,1,2,3", "", "0.001,1,2,3", "0.001,1,2,3"], "# sensor=adxl\nt_s,ax_m_s2,ay_m_s2,az_m_s2",
     r"line 6: column 't_s' does not increase"),
    (["0,1,2"], "t_s,ax_m_s2,ay_m_s2", r"missing column\(s\) az_m_s2"),
])
def test_bad_rows_name_file_line_field(tmp_path, rows, header, match):
    p = _write(tmp_path / "bad.csv", rows, header or "t_s,ax_m_s2,ay_m_s2,az_m_s2")
    with pytest.raises(AccelError, match=match) as ei:
        ReplayAccelerometer(p)
    assert "bad.csv" in str(ei.value)
