"""docs/recording_format.md against the code: each table on the page, read from the page,
is compared field by field with what the readers and writers do."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fydpad.texture import scan_io
from teleop import protocol as P
from teleop.master import StreamLog, build_report
from vision.mapping import roi_to_workspace
from vision.recording import (
    TRACK_COLUMNS,
    PadMeta,
    PadRecording,
    PadRecordingWriter,
    RecordingError,
    TrackWriter,
    parse_meta,
    read_track,
)

DOC = Path(__file__).resolve().parents[1] / "docs" / "recording_format.md"


def _section(title: str) -> str:
    """The text under the heading ``title`` up to the next heading of any level."""
    text = DOC.read_text(encoding="utf-8")
    m = re.search(rf"^#+ {re.escape(title)}\s*$(.*?)(?=^#)", text + "\n#", re.M | re.S)
    assert m, f"docs/recording_format.md has no section {title!r}"
    return m.group(1)


def _table(title: str) -> list[dict[str, str]]:
    """The first markdown table of a section, as one dict per row keyed by the header."""
    lines = [ln.strip() for ln in _section(title).splitlines() if ln.strip().startswith("|")]
    cells = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines]
    header, rows = cells[0], cells[2:]
    return [dict(zip(header, row, strict=True)) for row in rows]


def _names(cell: str) -> list[str]:
    """The backquoted names of a cell; ``a,b,c`` in one pair of backquotes gives three."""
    out: list[str] = []
    for quoted in re.findall(r"`([^`]*)`", cell):
        out.extend(quoted.split(","))
    return out


def _header(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()[0].split(",")


def _station_events_columns() -> tuple[str, ...]:
    """The columns the station gives its ``events.csv`` writer, read from its source."""
    import ast

    import fydpad.station.station as station

    tree = ast.parse(Path(station.__file__).read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and len(node.args) == 2
                and "events.csv" in ast.unparse(node.args[0])):
            return tuple(ast.literal_eval(node.args[1]))
    raise AssertionError("fydpad/station/station.py writes no events.csv")


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """A recording with every optional file, written by the code's own writer."""
    recdir = tmp_path_factory.mktemp("rec")
    meta = PadMeta(roi_px=(4, 3, 56, 42), workspace_mm=(100.0, 70.0), fps=30.0,
                   frame_size=(64, 48), image_flip="horizontal", ir_baseline_mm=(99, 98, 97))
    with PadRecordingWriter(recdir, meta, frame_times=True) as w:
        for k in range(3):
            w.write_frame(np.full((48, 64, 3), 200, np.uint8), t_s=k / 30.0)
            w.write_ir(k / 30.0, 1.0, 1.1, 1.2)
            w.write_force(k / 30.0, 0.5)
            w.write_truth(k / 30.0, k, k > 0, 1.0, 2.0, 0.5)
    return recdir


def test_session_files_have_the_documented_columns(written):
    rows = {_names(r["file"])[0]: r for r in _table("Pad session recording (a directory)")}
    # events.csv is written by the live station only (fydpad run --record): checked below.
    assert set(rows) == {"meta.json", "video.avi", "frames.csv", "ir.csv", "force.csv",
                         "truth.csv", "events.csv"}
    for name, row in rows.items():
        if name.endswith(".csv") and name != "events.csv":
            assert _header(written / name) == _names(row["columns"]), name
        if name.endswith(".csv"):
            assert row["required"] == "no", name
    assert rows["meta.json"]["required"] == rows["video.avi"]["required"] == "yes"
    assert sorted(p.name for p in written.iterdir()) == sorted(set(rows) - {"events.csv"})
    rec = PadRecording(written)  # and the reader takes what the writer wrote
    assert _names(rows["events.csv"]["columns"]) == list(_station_events_columns())
    assert rec.read_truth() is not None and rec.read_ir() is not None


def test_meta_keys_defaults_and_requirements_match_the_reader(written):
    rows = {_names(r["key"])[0]: r for r in _table("`meta.json`")}
    data = json.loads((written / "meta.json").read_text(encoding="utf-8"))
    flat = {k for k in data if k != "ir"} | {f"ir.{k}" for k in data["ir"]}
    assert flat == set(rows)  # the writer writes every documented key, and no other
    minimal = {"roi_px": [0, 0, 10, 10], "workspace_mm": [100.0, 70.0], "fps": 30.0}
    for key, row in rows.items():
        required = row["required"] == "yes"
        if key in minimal and key != "fps":
            assert required, key
            bad = {k: v for k, v in minimal.items() if k != key}
            with pytest.raises(RecordingError, match=key):
                parse_meta(bad, "m.json")
        elif key != "fps":
            assert row["required"] == "no", key
    meta = parse_meta(minimal)
    got = {"image_flip": meta.image_flip, "ir.sensors_mm": [list(p) for p in meta.ir_sensors_mm],
           "ir.base_to_fabric_mm": meta.base_to_fabric_mm}
    for key, value in got.items():
        default = json.loads(_names(rows[key]["default"])[0]
                             if key != "ir.sensors_mm" else rows[key]["default"].strip("`"))
        assert default == value, key
    assert meta.frame_size is None and meta.ir_baseline_mm is None
    assert "unless `frames.csv`" in rows["fps"]["required"]


def test_tracking_output_columns_match_the_writer(tmp_path):
    doc = [_names(r["column"])[0] for r in _table("Tracking output (`fydpad track`)")]
    assert tuple(doc) == TRACK_COLUMNS
    path = tmp_path / "track.csv"
    with TrackWriter(path, extra_columns=("u_px",)) as w:
        w.write_row(0.0, 0, False, 1.0, 2.0, 3.0, 7)
        w.write_row(0.033, 1, True, 1.0, 2.0, 3.0, 8)
    assert _header(path) == [*doc, "u_px"]  # more columns follow the six
    rows = path.read_text(encoding="utf-8").splitlines()
    assert rows[1].split(",")[2:6] == ["0", "", "", "0"]  # no contact: x, y empty, z 0
    back = read_track(path)
    assert math.isnan(back["x_mm"][0]) and back["x_mm"][1] == 1.0


@pytest.mark.filterwarnings("ignore:Mean of empty slice")  # best_lag_s on 3 samples
def test_report_keys_match_build_report():
    rows = {_names(r["key"])[0]: r for r in _table(
        "Tele-operation report (`fydpad replay --report`, `fydpad demo --out`)")}
    log = StreamLog(t_s=[0.0, 0.1, 0.2], master_mm=[(0, 0, 0), (1, 0, 0), (2, 0, 0)],
                    contact=[True, True, True], sent=3)
    for k, t in enumerate((0.0, 0.1, 0.2)):
        log.states.append((t, P.State(0, P.REASON_ACK, k + 1, t, t, t, (0, 0, 0), (0, 0, 0),
                                      k + 1, 0)))
        log.states.append((t, P.State(0, P.REASON_TICK, k + 1, t, t, t, (0, 0, 0),
                                      (float(k), 0, 0), k + 1, 0)))
    truth = np.array([[0.0, 1, 0, 0, 0], [0.1, 1, 1, 0, 0], [0.2, 1, 2, 0, 0]])
    rep = build_report(log, log, truth)
    assert set(rep) == set(rows)
    for key, row in rows.items():
        sub = [n for n in _names(row["meaning"].split(":")[0]) if '"' in n or n.isalpha()]
        if isinstance(rep[key], dict):
            assert set(rep[key]) == {s.strip('"{} ') for s in sub}, key
    assert "baseline_mae_mm" not in build_report(log, None)
    assert "truth_mae_mm" not in build_report(log, log)


def test_workspace_mapping_is_the_documented_formula():
    text = _section("Workspace frame and units")
    assert "x_mm = ((u - x) / w - 0.5) * W_mm" in text
    assert "y_mm = (0.5 - (v - y) / h) * H_mm" in text
    roi, ws = (10, 20, 160, 120), (100.0, 70.0)
    u, v = np.array([10.0, 90.0, 170.0]), np.array([20.0, 80.0, 140.0])
    x, y = roi_to_workspace(u, v, roi, ws)
    np.testing.assert_allclose(x, ((u - 10) / 160 - 0.5) * 100.0)
    np.testing.assert_allclose(y, (0.5 - (v - 20) / 120) * 70.0)
    assert x[1] == 0.0 and y[1] == 0.0  # the ROI's centre is the origin
    assert y[0] > 0  # the top of the image is away from the user: +y


def test_texture_scan_columns_match_the_reader():
    rows = _table("Texture scan recording (a CSV file)")
    required = tuple(_names(r["column"])[0] for r in rows if r["required"] == "yes")
    optional = tuple(_names(r["column"])[0] for r in rows if r["required"] == "no")
    assert required == scan_io.REQUIRED
    assert optional == scan_io.OPTIONAL


def test_slave_log_columns_match_the_writer():
    from fydpad.export.slave_log import SLAVE_LOG_COLUMNS

    doc = [n for r in _table("Slave log (`fydpad replay --slave-log CSV`)")
           for n in _names(r["column"])]
    assert tuple(doc) == SLAVE_LOG_COLUMNS
