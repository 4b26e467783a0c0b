"""The slave's command and actual position during a tele-operation pass, as a CSV on the
recording's clock: what ``fydpad replay --slave-log`` writes and ``fydpad export bag`` reads.

Columns: ``t_s,cmd_x_mm,cmd_y_mm,cmd_z_mm,actual_x_mm,actual_y_mm,actual_z_mm``, in the
workspace frame (z = indentation, as the finger's), one row per slave tick.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from teleop import protocol as P
from vision.recording import CsvRowWriter, read_csv_columns

SLAVE_LOG_COLUMNS = ("t_s", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm",
                     "actual_x_mm", "actual_y_mm", "actual_z_mm")


def slave_rows(session: object) -> NDArray[np.float64]:
    """Rows of SLAVE_LOG_COLUMNS from a finished ``teleop.master.Session``'s main pass.

    The slave stamps its ticks on its own clock; the pass's offset maps them to the
    master's, and the pass's start maps that to the recording's ``t_s``.
    """
    main = session.main  # type: ignore[attr-defined]
    off = main.offset_s()
    ticks = sorted({st.t_slave_s: st for _, st in main.states
                    if st.reason == P.REASON_TICK}.items())
    if not ticks:
        return np.empty((0, len(SLAVE_LOG_COLUMNS)))
    t_rec = np.array([t for t, _ in ticks]) - off - main.t0_s + main.t_s0
    cmd = np.array([st.cmd_mm for _, st in ticks], float)
    act = np.array([st.actual_mm for _, st in ticks], float)
    return np.column_stack([t_rec, cmd, act])


def write_slave_log(session: object, path: str | Path) -> Path:
    """Write the main pass's slave log (``slave_rows``) to ``path``."""
    path = Path(path)
    with CsvRowWriter(path, SLAVE_LOG_COLUMNS) as w:
        for row in slave_rows(session):
            w.write(*(float(v) for v in row))
    return path


def read_slave_log(path: str | Path) -> dict[str, NDArray[np.float64]]:
    """The columns of a slave log; errors name the file, line and column."""
    return read_csv_columns(path, SLAVE_LOG_COLUMNS)
