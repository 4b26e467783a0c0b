"""Readers and writers for the pad session recording and the tracking output.

The formats are the contract of docs/recording_format.md; every error names the file
and the key, or the line number (the header is line 1).
"""

from __future__ import annotations

import csv
import json
import math
import os
import stat
import time
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import UserError
from vision.strict_json import finite

IMAGE_FLIPS = ("none", "horizontal", "vertical", "both")
DEFAULT_IR_SENSORS_MM: tuple[tuple[float, float], ...] = ((-22.0, -3.0), (0.0, 27.0), (22.0, -3.0))
DEFAULT_BASE_TO_FABRIC_MM = 100.0
TRACK_COLUMNS = ("t_s", "frame", "contact", "x_mm", "y_mm", "indentation_mm")
TRUTH_COLUMNS = ("t_s", "frame", "contact", "x_mm", "y_mm", "indentation_mm")
VIDEO_NAMES = ("video.avi", "video.mp4")


class RecordingError(UserError, ValueError):
    """A recording file is missing or malformed; the message names the file and key or line."""


# --------------------------------------------------------------------------- meta.json


@dataclass
class PadMeta:
    """The contents of ``meta.json`` with the format's defaults filled in."""

    roi_px: tuple[int, int, int, int]
    workspace_mm: tuple[float, float]
    fps: float | None = None
    frame_size: tuple[int, int] | None = None
    image_flip: str = "none"
    ir_sensors_mm: tuple[tuple[float, float], ...] = DEFAULT_IR_SENSORS_MM
    base_to_fabric_mm: float = DEFAULT_BASE_TO_FABRIC_MM
    ir_baseline_mm: tuple[float, float, float] | None = None
    #: Keys this reader does not know, kept so a rewrite loses nothing.
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = dict(self.extra)
        if self.fps is not None:
            out["fps"] = float(self.fps)
        if self.frame_size is not None:
            out["frame_size"] = [int(v) for v in self.frame_size]
        out["roi_px"] = [int(v) for v in self.roi_px]
        out["image_flip"] = self.image_flip
        out["workspace_mm"] = [float(v) for v in self.workspace_mm]
        ir: dict[str, Any] = dict(out.get("ir", {}))
        ir["sensors_mm"] = [[float(a), float(b)] for a, b in self.ir_sensors_mm]
        ir["base_to_fabric_mm"] = float(self.base_to_fabric_mm)
        if self.ir_baseline_mm is not None:
            ir["baseline_mm"] = [float(v) for v in self.ir_baseline_mm]
        out["ir"] = ir
        return out


def _number_list(value: Any, n: int, where: str, integer: bool = False) -> list[float]:
    if not isinstance(value, list) or len(value) != n:
        raise RecordingError(f"{where}: expected a list of {n} numbers, got {value!r}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise RecordingError(f"{where}: expected a list of {n} numbers, got {value!r}")
        if integer and float(v) != int(v):
            raise RecordingError(f"{where}: expected whole pixel numbers, got {value!r}")
        out.append(v)
    return out


def parse_meta(data: Any, path: str | Path = "meta.json") -> PadMeta:
    """Validate a decoded ``meta.json`` object; errors name ``path`` and the key."""
    p = str(path)
    if not isinstance(data, dict):
        raise RecordingError(f"{p}: expected a JSON object at the top level")
    for key in ("roi_px", "workspace_mm"):
        if key not in data:
            raise RecordingError(f"{p}: missing required key '{key}'")
    roi = _number_list(data["roi_px"], 4, f"{p}: key 'roi_px'", integer=True)
    if roi[2] <= 0 or roi[3] <= 0 or roi[0] < 0 or roi[1] < 0:
        raise RecordingError(f"{p}: key 'roi_px': width and height must be positive, got {roi}")
    ws = _number_list(data["workspace_mm"], 2, f"{p}: key 'workspace_mm'")
    if ws[0] <= 0 or ws[1] <= 0:
        raise RecordingError(f"{p}: key 'workspace_mm': sizes must be positive, got {ws}")
    fps = data.get("fps")
    if fps is not None and (
        isinstance(fps, bool) or not isinstance(fps, int | float) or not fps > 0
    ):
        raise RecordingError(f"{p}: key 'fps': expected a positive number, got {fps!r}")
    frame_size = data.get("frame_size")
    if frame_size is not None:
        fs = _number_list(frame_size, 2, f"{p}: key 'frame_size'", integer=True)
        frame_size = (int(fs[0]), int(fs[1]))
        if roi[0] + roi[2] > fs[0] or roi[1] + roi[3] > fs[1]:
            raise RecordingError(f"{p}: key 'roi_px': {roi} lies outside frame_size {fs}")
    flip = data.get("image_flip", "none")
    if flip not in IMAGE_FLIPS:
        raise RecordingError(f"{p}: key 'image_flip': expected one of {IMAGE_FLIPS}, got {flip!r}")
    ir = data.get("ir", {})
    if not isinstance(ir, dict):
        raise RecordingError(f"{p}: key 'ir': expected an object")
    sensors: tuple[tuple[float, float], ...] = DEFAULT_IR_SENSORS_MM
    if "sensors_mm" in ir:
        raw = ir["sensors_mm"]
        if not isinstance(raw, list) or len(raw) != 3:
            raise RecordingError(f"{p}: key 'ir.sensors_mm': expected three [x, y] pairs")
        sensors = tuple(
            tuple(_number_list(s, 2, f"{p}: key 'ir.sensors_mm[{i}]'")) for i, s in enumerate(raw)
        )  # type: ignore[assignment]
        (ax, ay), (bx, by), (cx, cy) = sensors
        if abs((bx - ax) * (cy - ay) - (by - ay) * (cx - ax)) < 1e-6:
            raise RecordingError(
                f"{p}: key 'ir.sensors_mm': the three sensors are collinear, so no plane "
                "passes through their points (paper II-C)"
            )
    base = ir.get("base_to_fabric_mm", DEFAULT_BASE_TO_FABRIC_MM)
    if isinstance(base, bool) or not isinstance(base, int | float) or not base > 0:
        raise RecordingError(f"{p}: key 'ir.base_to_fabric_mm': expected a positive number")
    baseline = None
    if "baseline_mm" in ir:
        baseline = tuple(_number_list(ir["baseline_mm"], 3, f"{p}: key 'ir.baseline_mm'"))
    known = {"fps", "frame_size", "roi_px", "image_flip", "workspace_mm", "ir"}
    extra = {k: v for k, v in data.items() if k not in known}
    ir_extra = {k: v for k, v in ir.items() if k not in ("sensors_mm", "base_to_fabric_mm",
                                                         "baseline_mm")}
    if ir_extra:
        extra["ir"] = ir_extra
    return PadMeta(
        roi_px=(int(roi[0]), int(roi[1]), int(roi[2]), int(roi[3])),
        workspace_mm=(float(ws[0]), float(ws[1])),
        fps=None if fps is None else float(fps),
        frame_size=frame_size,
        image_flip=flip,
        ir_sensors_mm=sensors,
        base_to_fabric_mm=float(base),
        ir_baseline_mm=baseline,  # type: ignore[arg-type]
        extra=extra,
    )


def read_meta(recdir: str | Path) -> PadMeta:
    path = Path(recdir) / "meta.json"
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RecordingError(f"{path}: missing (a pad session recording needs meta.json)") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot be read ({exc.strerror})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    return parse_meta(data, path)


def write_meta(recdir: str | Path, meta: PadMeta) -> Path:
    path = Path(recdir) / "meta.json"
    path.write_text(json.dumps(finite(meta.to_json()), indent=2, allow_nan=False) + "\n",
                    encoding="utf-8")
    return path


# --------------------------------------------------------------------------- CSV


def read_csv_columns(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    empty_ok: Sequence[str] = (),
) -> dict[str, NDArray[np.float64]]:
    """Read a numeric CSV with a header row into float columns.

    Lines starting with ``#`` before the header are comments. ``empty_ok`` columns
    may hold empty cells, read as NaN; any other empty or non-numeric cell is an
    error naming the file, line and column.
    """
    path = Path(path)
    try:
        fh = path.open(newline="", encoding="utf-8")
    except FileNotFoundError:
        raise RecordingError(f"{path}: missing") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot be read ({exc.strerror})") from None
    with fh:
        reader = csv.reader(fh)
        header: list[str] | None = None
        for row in reader:
            if row and row[0].lstrip().startswith("#"):
                continue
            header = [h.strip() for h in row]
            break
        if header is None:
            raise RecordingError(f"{path}: empty file (expected a header row)")
        header_line = reader.line_num
        missing = [c for c in required if c not in header]
        if missing:
            raise RecordingError(
                f"{path}: line {header_line}: missing column(s) {', '.join(missing)} "
                f"(header is {','.join(header)})"
            )
        wanted = [c for c in (*required, *optional) if c in header]
        index = {c: header.index(c) for c in wanted}
        columns: dict[str, list[float]] = {c: [] for c in wanted}
        allow_empty = set(empty_ok)
        for row in reader:
            line = reader.line_num
            if not row or (len(row) == 1 and not row[0].strip()):
                continue
            if len(row) != len(header):
                raise RecordingError(
                    f"{path}: line {line}: expected {len(header)} fields, got {len(row)}"
                )
            for c, i in index.items():
                cell = row[i].strip()
                if cell == "":
                    if c in allow_empty:
                        columns[c].append(math.nan)
                        continue
                    raise RecordingError(f"{path}: line {line}: column '{c}' is empty")
                try:
                    value = float(cell)
                except ValueError:
                    raise RecordingError(
                        f"{path}: line {line}: column '{c}': {cell!r} is not a number"
                    ) from None
                if not math.isfinite(value):
                    raise RecordingError(
                        f"{path}: line {line}: column '{c}': {cell!r} is not finite"
                    )
                columns[c].append(value)
    return {c: np.asarray(v, dtype=np.float64) for c, v in columns.items()}


def csv_data_line(path: str | Path, row: int) -> int:
    """The file line (1-based) of data row ``row`` (0-based) as :func:`read_csv_columns`
    counts rows (``#`` lines before the header, the header, blank lines skipped); -1 if
    there is no such row. For error messages only: it reads the file again."""
    with Path(path).open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        for r in reader:
            if not (r and r[0].lstrip().startswith("#")):
                break  # the header
        k = -1
        for r in reader:
            if not r or (len(r) == 1 and not r[0].strip()):
                continue
            k += 1
            if k == row:
                return reader.line_num
    return -1


def _check_increasing(path: Path, t_s: NDArray[np.float64]) -> None:
    bad = np.flatnonzero(np.diff(t_s) < 0)
    if bad.size:
        # diff index i compares data rows i and i + 1: the later one is at fault.
        line = csv_data_line(path, int(bad[0]) + 1)
        raise RecordingError(f"{path}: line {line}: column 't_s' goes back in time")


class CsvRowWriter:
    """Writes a CSV row by row and hands it to the OS at least every ``flush_every_s``
    seconds, so a killed process keeps what it wrote."""

    def __init__(
        self,
        path: str | Path,
        columns: Sequence[str],
        comment: str | None = None,
        flush_every_s: float = 0.5,
    ):
        self.path = Path(path)
        self.columns = tuple(columns)
        self._fh: IO[str] = self.path.open("w", newline="", encoding="utf-8")
        if comment:
            self._fh.write(f"# {comment}\n")
        self._fh.write(",".join(self.columns) + "\n")
        self._flush_every_s = flush_every_s
        self._last_flush = time.monotonic()

    def write(self, *values: object) -> None:
        self._fh.write(",".join(_fmt(v) for v in values) + "\n")
        now = time.monotonic()
        if now - self._last_flush >= self._flush_every_s:
            self._fh.flush()
            self._last_flush = now

    def write_rows(self, rows: Iterable[Sequence[object]]) -> None:
        """Many rows in one write (a log's writer thread, a chunk at a time)."""
        self._fh.write("".join(",".join(map(_fmt, r)) + "\n" for r in rows))
        now = time.monotonic()
        if now - self._last_flush >= self._flush_every_s:
            self._fh.flush()
            self._last_flush = now

    def flush(self) -> None:
        self._fh.flush()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.flush()
            if stat.S_ISREG(os.fstat(self._fh.fileno()).st_mode):  # a pipe has no fsync
                os.fsync(self._fh.fileno())
            self._fh.close()

    def __enter__(self) -> CsvRowWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _fmt(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, bool | np.bool_):
        return "1" if v else "0"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        if not math.isfinite(v):
            return ""
        # Six decimals: microseconds for t_s, well below every sensor's resolution.
        text = f"{float(v):.6f}".rstrip("0").rstrip(".")
        return "0" if text == "-0" else text
    return str(v)


# --------------------------------------------------------------------------- video


def open_video(path: str | Path) -> cv2.VideoCapture:
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: missing")
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise RecordingError(f"{path}: OpenCV cannot open it as a video")
    return cap


def find_video(recdir: str | Path) -> Path:
    for name in VIDEO_NAMES:
        p = Path(recdir) / name
        if p.exists():
            return p
    raise RecordingError(f"{Path(recdir)}: missing video (expected {' or '.join(VIDEO_NAMES)})")


@dataclass
class Truth:
    t_s: NDArray[np.float64]
    frame: NDArray[np.int64]
    contact: NDArray[np.bool_]
    x_mm: NDArray[np.float64]
    y_mm: NDArray[np.float64]
    indentation_mm: NDArray[np.float64]


def _last_time(path: Path) -> float | None:
    """The last row's t_s (first column) of a CSV file, or None when absent or empty."""
    if not path.exists():
        return None
    with path.open("rb") as fh:
        fh.seek(0, os.SEEK_END)
        fh.seek(max(0, fh.tell() - 4096))
        lines = fh.read().decode("utf-8", "replace").strip().splitlines()
    for line in reversed(lines):
        try:
            return float(line.split(",", 1)[0])
        except ValueError:
            continue  # the header, or a torn line
    return None


class TruncatedVideo(RecordingError):
    """The video ends (or stops decoding) before the recording's other files do."""


class PadRecording:
    """A pad session recording directory, read lazily.

    ``frames()`` streams the video one frame at a time; the sensor files are read
    on demand and validated, each error naming its file and line. A video that ends
    before frames.csv, ir.csv, force.csv or truth.csv does (truncated, or a frame that
    fails to decode) raises :class:`TruncatedVideo` after the last good frame, unless
    ``allow_truncated`` is set (``--allow-truncated``): then ``truncation`` says what was
    cut and the frames simply stop.
    """

    #: Set by ``--allow-truncated``: a short video ends the frames instead of raising.
    allow_truncated: bool = False

    def __init__(self, recdir: str | Path):
        self.path = Path(recdir)
        if not self.path.is_dir():
            raise RecordingError(f"{self.path}: not a directory (expected a pad session recording)")
        self.meta = read_meta(self.path)
        self.video_path = find_video(self.path)
        frames_csv = self.path / "frames.csv"
        self._frame_times: NDArray[np.float64] | None = None
        if frames_csv.exists():
            cols = read_csv_columns(frames_csv, ("t_s", "frame"))
            _check_increasing(frames_csv, cols["t_s"])
            order = np.argsort(cols["frame"], kind="stable")
            frames = cols["frame"][order]
            if not np.array_equal(frames, np.arange(frames.size)):
                raise RecordingError(f"{frames_csv}: column 'frame' must number frames 0..N-1")
            self._frame_times = cols["t_s"][order]
        elif self.meta.fps is None:
            raise RecordingError(
                f"{self.path / 'meta.json'}: missing required key 'fps' (there is no frames.csv)"
            )
        cap = open_video(self.video_path)
        try:
            self.frame_count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            w = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
            h = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            self.video_fps = float(cap.get(cv2.CAP_PROP_FPS))
        finally:
            cap.release()
        self.video_size = (w, h)
        #: The message of a truncation met with allow_truncated set, else None.
        self.truncation: str | None = None
        if self.meta.frame_size is not None and tuple(self.meta.frame_size) != (w, h):
            raise RecordingError(
                f"{self.path / 'meta.json'}: key 'frame_size' is {list(self.meta.frame_size)} "
                f"but {self.video_path.name} is {w}x{h}"
            )
        x, y, rw, rh = self.meta.roi_px
        if x + rw > w or y + rh > h:
            raise RecordingError(
                f"{self.path / 'meta.json'}: key 'roi_px' {list(self.meta.roi_px)} lies outside "
                f"the {w}x{h} frames of {self.video_path.name}"
            )

    @property
    def fps(self) -> float:
        if self.meta.fps is not None:
            return self.meta.fps
        t = self.frame_times()
        return float((t.size - 1) / (t[-1] - t[0])) if t.size > 1 else 30.0

    def frame_time(self, k: int) -> float:
        if self._frame_times is not None:
            if k >= self._frame_times.size:
                raise RecordingError(
                    f"{self.path / 'frames.csv'}: no time for frame {k} "
                    f"(the video has more frames than the file lists)"
                )
            return float(self._frame_times[k])
        return k / float(self.meta.fps)  # type: ignore[arg-type]

    def frame_times(self) -> NDArray[np.float64]:
        if self._frame_times is not None:
            return self._frame_times
        return np.arange(self.frame_count) / float(self.meta.fps)  # type: ignore[arg-type]

    def frames(self) -> Iterator[tuple[int, float, NDArray[np.uint8]]]:
        """Yield ``(frame_index, t_s, raw_bgr_frame)`` one at a time (not flipped)."""
        cap = open_video(self.video_path)
        try:
            k = 0
            while True:
                ok, frame = cap.read()
                if not ok:
                    self._check_complete(k)
                    break
                h, w = frame.shape[:2]
                if (w, h) != self.video_size:
                    raise RecordingError(
                        f"{self.video_path}: frame {k} is {w}x{h}, expected "
                        f"{self.video_size[0]}x{self.video_size[1]}"
                    )
                yield k, self.frame_time(k), frame
                k += 1
        finally:
            cap.release()

    def _check_complete(self, n_read: int) -> None:
        """After the video's last decodable frame: do the other files end there too?

        frames.csv must list exactly the frames read. Without it the video's end is its
        frame count over meta.json's fps, and a sensor or truth file may run on by a frame
        period plus 5 % (its own rate is not the camera's, and a live camera's true rate
        drifts from its nominal one)."""
        if self._frame_times is not None:
            if n_read >= self._frame_times.size:
                return
            longer = (f"frames.csv lists {self._frame_times.size} frames "
                      f"(to {self._frame_times[-1]:.2f} s)")
        else:
            period = 1.0 / float(self.meta.fps)  # type: ignore[arg-type]
            t_video_end = n_read * period
            longer = ""
            for name in ("truth.csv", "ir.csv", "force.csv"):
                t_last = _last_time(self.path / name)
                if t_last is not None and t_last > 1.05 * t_video_end + period:
                    longer = f"{name} runs on to {t_last:.2f} s"
                    break
            if not longer:
                return
        last = f"frame {n_read - 1}" if n_read else "no frame"
        message = (f"{self.video_path}: the video ends after {last} (the last good one: "
                   f"truncated or a frame that does not decode), while {longer}")
        if not self.allow_truncated:
            raise TruncatedVideo(message + "; --allow-truncated uses the frames before it")
        self.truncation = message
        warnings.warn(message + " (--allow-truncated: the frames before it are used)",
                      stacklevel=2)

    # Sensor files -----------------------------------------------------------

    def has(self, name: str) -> bool:
        return (self.path / name).exists()

    def read_ir(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """``(t_s, volts[n, 3])`` from ``ir.csv``, or None when the file is absent."""
        p = self.path / "ir.csv"
        if not p.exists():
            return None
        cols = read_csv_columns(p, ("t_s", "v0", "v1", "v2"))
        _check_increasing(p, cols["t_s"])
        return cols["t_s"], np.column_stack([cols["v0"], cols["v1"], cols["v2"]])

    def read_force(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        p = self.path / "force.csv"
        if not p.exists():
            return None
        cols = read_csv_columns(p, ("t_s", "force_n"))
        _check_increasing(p, cols["t_s"])
        return cols["t_s"], cols["force_n"]

    def read_truth(self) -> Truth | None:
        p = self.path / "truth.csv"
        if not p.exists():
            return None
        cols = read_csv_columns(p, TRUTH_COLUMNS, empty_ok=("x_mm", "y_mm"))
        contact = cols["contact"] != 0
        bad = np.flatnonzero(contact & ~np.isfinite(cols["x_mm"]))
        if bad.size:
            raise RecordingError(f"{p}: line {int(bad[0]) + 2}: contact is 1 but x_mm is empty")
        return Truth(
            t_s=cols["t_s"],
            frame=cols["frame"].astype(np.int64),
            contact=contact,
            x_mm=cols["x_mm"],
            y_mm=cols["y_mm"],
            indentation_mm=cols["indentation_mm"],
        )


class PadRecordingWriter:
    """Writes a pad session recording as it goes: frames, sensors and truth row by row.

    The video is MJPG in ``video.avi`` by default (``video.mp4`` with the ``mp4v``
    codec for smaller files). ``meta.json`` is written first, so a killed writer leaves
    a readable recording of what it had.
    """

    def __init__(
        self,
        recdir: str | Path,
        meta: PadMeta,
        video_name: str = "video.avi",
        jpeg_quality: int = 90,
        frame_times: bool = False,
    ):
        if video_name not in VIDEO_NAMES:
            raise ValueError(f"video_name must be one of {VIDEO_NAMES}")
        if meta.fps is None:
            raise ValueError("meta.fps is needed to write a video")
        if meta.frame_size is None:
            raise ValueError("meta.frame_size is needed to write a video")
        self.path = Path(recdir)
        self.path.mkdir(parents=True, exist_ok=True)
        self.meta = meta
        write_meta(self.path, meta)
        if video_name.endswith(".avi"):
            # OpenCV's own MJPEG writer: the only backend that honours the JPEG quality.
            self._video = cv2.VideoWriter(
                str(self.path / video_name), cv2.CAP_OPENCV_MJPEG,
                cv2.VideoWriter_fourcc(*"MJPG"), float(meta.fps), tuple(meta.frame_size),
            )
        else:
            self._video = cv2.VideoWriter(
                str(self.path / video_name), cv2.VideoWriter_fourcc(*"mp4v"), float(meta.fps),
                tuple(meta.frame_size),
            )
        if not self._video.isOpened():
            raise RecordingError(f"{self.path / video_name}: OpenCV cannot write this video")
        self._video.set(cv2.VIDEOWRITER_PROP_QUALITY, float(jpeg_quality))
        self._frames = (
            CsvRowWriter(self.path / "frames.csv", ("t_s", "frame")) if frame_times else None
        )
        self._ir: CsvRowWriter | None = None
        self._force: CsvRowWriter | None = None
        self._truth: CsvRowWriter | None = None
        self.frame_count = 0

    def write_frame(self, frame_bgr: NDArray[np.uint8], t_s: float | None = None) -> int:
        h, w = frame_bgr.shape[:2]
        if (w, h) != tuple(self.meta.frame_size):  # type: ignore[arg-type]
            raise ValueError(f"frame is {w}x{h}, the recording is {self.meta.frame_size}")
        self._video.write(frame_bgr)
        if self._frames is not None:
            self._frames.write(self.frame_count / self.meta.fps if t_s is None else t_s,
                               self.frame_count)
        self.frame_count += 1
        return self.frame_count - 1

    def write_ir(self, t_s: float, v0: float, v1: float, v2: float) -> None:
        if self._ir is None:
            self._ir = CsvRowWriter(self.path / "ir.csv", ("t_s", "v0", "v1", "v2"))
        self._ir.write(t_s, v0, v1, v2)

    def write_force(self, t_s: float, force_n: float) -> None:
        if self._force is None:
            self._force = CsvRowWriter(self.path / "force.csv", ("t_s", "force_n"))
        self._force.write(t_s, force_n)

    def write_truth(
        self, t_s: float, frame: int, contact: bool, x_mm: float, y_mm: float,
        indentation_mm: float,
    ) -> None:
        if self._truth is None:
            self._truth = CsvRowWriter(self.path / "truth.csv", TRUTH_COLUMNS)
        if contact:
            self._truth.write(t_s, frame, 1, x_mm, y_mm, indentation_mm)
        else:
            self._truth.write(t_s, frame, 0, None, None, 0.0)

    def close(self) -> None:
        self._video.release()
        for w in (self._frames, self._ir, self._force, self._truth):
            if w is not None:
                w.close()

    def __enter__(self) -> PadRecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- tracking output


class TrackWriter(CsvRowWriter):
    """The tracking output of ``fydpad track``, one row per frame, written as it goes."""

    def __init__(self, path: str | Path, extra_columns: Sequence[str] = ()):
        super().__init__(path, (*TRACK_COLUMNS, *extra_columns))

    def write_row(
        self,
        t_s: float,
        frame: int,
        contact: bool,
        x_mm: float | None,
        y_mm: float | None,
        indentation_mm: float | None,
        *extra: object,
    ) -> None:
        if not contact:
            x_mm = y_mm = None
            if indentation_mm is not None and math.isfinite(indentation_mm):
                indentation_mm = 0.0
        self.write(t_s, frame, 1 if contact else 0, x_mm, y_mm, indentation_mm, *extra)


def read_track(path: str | Path) -> dict[str, NDArray[np.float64]]:
    """Read a tracking output CSV; extra numeric columns after the six are kept."""
    path = Path(path)
    with path.open(encoding="utf-8") as fh:
        header = fh.readline().strip().split(",")
    extra = [c for c in header if c not in TRACK_COLUMNS]
    return read_csv_columns(
        path, TRACK_COLUMNS, optional=extra,
        empty_ok=("x_mm", "y_mm", "indentation_mm", *extra),
    )
