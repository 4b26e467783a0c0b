"""Texture scan recordings (docs/recording_format.md, "Texture scan recording").

``t_s,ax,ay,az`` then optional ``speed_mm_s, x_mm, y_mm, force_n, friction_n``; a
``# key=value ...`` comment line carries metadata (``surface=``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.signal as ss
from numpy.typing import NDArray

from fydpad.errors import UserError
from vision.recording import CsvRowWriter, RecordingError, csv_data_line, read_csv_columns

Array = NDArray[np.float64]
REQUIRED = ("t_s", "ax", "ay", "az")
OPTIONAL = ("speed_mm_s", "x_mm", "y_mm", "force_n", "friction_n")


@dataclass
class Scan:
    """One scan: evenly sampled 3-axis acceleration and the scanning speed (the optional
    columns None when absent or with empty cells)."""

    path: str
    fs_hz: float
    t_s: Array
    acc: Array  # (n, 3) m/s^2
    speed_mm_s: Array
    force_n: Array | None = None
    meta: dict[str, str] = field(default_factory=dict)
    x_mm: Array | None = None
    friction_n: Array | None = None

    @property
    def surface(self) -> str:
        """The ``# surface=`` label, else the file name without extension."""
        return self.meta.get("surface") or Path(self.path).stem


#: ``key=value``: a value runs to the next `` key=`` (so ``surface=Paper Plate 2`` is one).
_PAIR = re.compile(r"(\S+?)=(.*?)\s*(?=\s\S+?=|$)")


def read_metadata(path: str | Path) -> dict[str, str]:
    """``key=value`` pairs of the ``#`` comment lines before the header (a value may hold
    spaces: it runs to the next ``key=``)."""
    meta: dict[str, str] = {}
    try:
        with Path(path).open(encoding="utf-8") as fh:
            for line in fh:
                if not line.lstrip().startswith("#"):
                    break
                meta.update(_PAIR.findall(line.lstrip()[1:]))
    except OSError:
        pass
    return meta


def speed_from_position(t_s: Array, x_mm: Array, y_mm: Array, cutoff_hz: float = 10.0) -> Array:
    """|d(x, y)/dt| low-passed at ``cutoff_hz`` (zero phase: offline), in mm/s."""
    fs = 1.0 / float(np.median(np.diff(t_s)))
    vx = np.gradient(x_mm, t_s)
    vy = np.gradient(y_mm, t_s)
    if cutoff_hz < fs / 2 and t_s.size > 15:
        sos = ss.butter(2, cutoff_hz, fs=fs, output="sos")
        vx = ss.sosfiltfilt(sos, vx)
        vy = ss.sosfiltfilt(sos, vy)
    return np.hypot(vx, vy)


def read_scan(path: str | Path, rate_tolerance: float = 0.01) -> Scan:
    """Read and check a scan; errors name the file and the field."""
    path = Path(path)
    cols = read_csv_columns(path, REQUIRED, OPTIONAL, empty_ok=OPTIONAL)
    t = cols["t_s"]
    if t.size < 16:
        raise RecordingError(f"{path}: only {t.size} samples in column 't_s'")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0])
        raise RecordingError(f"{path}: line {csv_data_line(path, i + 1)}: column 't_s' does not "
                             "increase")
    med = float(np.median(dt))
    dev = np.abs(dt - med) > rate_tolerance * med
    if np.any(dev):
        i = int(np.flatnonzero(dev)[0])
        raise RecordingError(
            f"{path}: line {csv_data_line(path, i + 1)}: column 't_s' is unevenly sampled (step "
            f"{dt[i]:.6g} s against {med:.6g} s); resample the recording to a constant rate"
        )
    acc = np.column_stack([cols["ax"], cols["ay"], cols["az"]])
    if "speed_mm_s" in cols and np.isfinite(cols["speed_mm_s"]).all():
        speed = np.abs(cols["speed_mm_s"])
    elif "x_mm" in cols and "y_mm" in cols and np.isfinite(cols["x_mm"]).all() \
            and np.isfinite(cols["y_mm"]).all():
        speed = speed_from_position(t, cols["x_mm"], cols["y_mm"])
    else:
        have = [c for c in ("speed_mm_s", "x_mm", "y_mm") if c in cols]
        why = "has empty cells" if have else "is missing"
        raise RecordingError(
            f"{path}: column 'speed_mm_s' (or 'x_mm','y_mm') {why}: the scanning speed "
            "is needed to index the models"
        )
    full = {k: c for k, c in cols.items() if np.isfinite(c).all()}
    fs = float(f"{1.0 / med:.9g}")  # 1/median(dt) of printed times: drop rounding noise
    return Scan(str(path), fs, t, acc, speed, full.get("force_n"), read_metadata(path),
                full.get("x_mm"), full.get("friction_n"))


def read_scans(paths: list[str]) -> list[Scan]:
    """:func:`read_scan` of each, a bad file a UserError."""
    try:
        return [read_scan(p) for p in paths]
    except RecordingError as exc:
        raise UserError(str(exc)) from None


def write_scan(
    path: str | Path, t_s: Array, acc: Array, speed_mm_s: Array | None = None,
    x_mm: Array | None = None, y_mm: Array | None = None, force_n: Array | None = None,
    meta: dict[str, str] | None = None,
) -> Path:
    """Write a scan CSV in the contract's column order."""
    given = {"t_s": t_s, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
             "speed_mm_s": speed_mm_s, "x_mm": x_mm, "y_mm": y_mm, "force_n": force_n}
    cols = {k: c for k, c in given.items() if c is not None}
    comment = " ".join(f"{k}={v}" for k, v in (meta or {}).items()) or None
    with CsvRowWriter(path, tuple(cols), comment=comment, flush_every_s=math.inf) as w:
        for row in np.column_stack(list(cols.values())):
            w.write(*(float(v) for v in row))
    return Path(path)
