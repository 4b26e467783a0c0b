"""``fydpad export bag``: written with rosbags, read back with the independent MCAP readers
(mcap + mcap-ros2-support), every value compared with the recording's files."""

from __future__ import annotations

import csv
import math
import shutil
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the ros extra (pip install 'fydpad[ros]') is absent")
pytest.importorskip("mcap_ros2", reason="the independent reader mcap-ros2-support is absent")

import cv2
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from fydpad.cli import main
from fydpad.config import load_config
from fydpad.export.bag import TOPICS, export_bag
from vision.indentation import IndentationEstimator
from vision.recording import read_csv_columns, read_meta

ROOT = Path(__file__).resolve().parents[2]
RECORDINGS = ROOT / "recordings"
BUNDLED = ("circle", "hard", "lissajous", "tapping")
DEVICE = RECORDINGS / "device.toml"


def _read_bag(bag: Path) -> dict[str, list]:
    """topic -> [(log_time_ns, message)], by the independent reader."""
    (mcap,) = bag.glob("*.mcap")
    out: dict[str, list] = defaultdict(list)
    with mcap.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            out[channel.topic].append((message.log_time, decoded))
    return out


def _ns(t_s: float) -> int:
    return round(t_s * 1e9)


def _stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def _copy_with_track(name: str, tmp: Path) -> Path:
    """The recording with a tracking output: truth.csv's columns as track.csv."""
    rec = tmp / name
    shutil.copytree(RECORDINGS / name, rec)
    with (rec / "truth.csv").open() as fh, (rec / "track.csv").open("w") as out:
        out.write("t_s,frame,contact,x_mm,y_mm,indentation_mm\n")
        for row in csv.DictReader(fh):
            out.write(",".join(row[k] for k in ("t_s", "frame", "contact", "x_mm", "y_mm",
                                                "indentation_mm")) + "\n")
    return rec


def _check_finger(msgs: dict, rec: Path, name: str, prefix: str) -> None:
    cols = read_csv_columns(rec / name, ("t_s", "contact", "x_mm", "y_mm", "indentation_mm"),
                            empty_ok=("x_mm", "y_mm"))
    on = cols["contact"] != 0
    poses = msgs[f"{prefix}/pose"]
    assert len(poses) == int(on.sum()) > 0
    for (t_log, msg), t, x, y, d in zip(poses, cols["t_s"][on], cols["x_mm"][on],
                                        cols["y_mm"][on], cols["indentation_mm"][on],
                                        strict=True):
        assert t_log == _stamp_ns(msg.header) == _ns(t)
        assert msg.header.frame_id == "fydpad_workspace"
        p = msg.pose.position
        assert (p.x, p.y, p.z) == (x / 1000.0, y / 1000.0, -d / 1000.0)
    if prefix == "/fydpad/finger":
        contact = msgs[f"{prefix}/contact"]
        assert [m.data for _, m in contact] == list(on)
        assert [t for t, _ in contact] == [_ns(t) for t in cols["t_s"]]
        assert [m.data for _, m in msgs[f"{prefix}/indentation_mm"]] == list(
            cols["indentation_mm"])


def _check_sensors(msgs: dict, rec: Path) -> None:
    force = read_csv_columns(rec / "force.csv", ("t_s", "force_n"))
    got = msgs["/fydpad/force"]
    assert [t for t, _ in got] == [_ns(t) for t in force["t_s"]]
    assert [m.wrench.force.z for _, m in got] == list(-force["force_n"])
    assert all(m.wrench.force.x == m.wrench.torque.z == 0.0 for _, m in got)
    ir = read_csv_columns(rec / "ir.csv", ("t_s", "v0", "v1", "v2"))
    volts = np.column_stack([ir["v0"], ir["v1"], ir["v2"]])
    got_v = np.array([m.data for _, m in msgs["/fydpad/ir/volts"]])
    np.testing.assert_array_equal(got_v, volts)
    meta = read_meta(rec)
    est = IndentationEstimator.from_config(load_config(DEVICE).ir,
                                           sensors_mm=meta.ir_sensors_mm,
                                           baseline_mm=meta.ir_baseline_mm,
                                           base_to_fabric_mm=meta.base_to_fabric_mm)
    dist_mm, _ = est.distances_mm(volts)
    for j in range(3):
        got_r = msgs[f"/fydpad/ir/range{j}"]
        assert [t for t, _ in got_r] == [_ns(t) for t in ir["t_s"]]
        # Range.range is a float32: equal to the distance rounded to float32.
        np.testing.assert_array_equal(np.array([m.range for _, m in got_r], np.float32),
                                      (dist_mm[:, j] / 1000.0).astype(np.float32))
        assert {m.header.frame_id for _, m in got_r} == {f"fydpad_ir{j}"}
    # Distances, not voltages: the fabric about 100 mm above the sensors at rest.
    assert 90.0 < float(np.median(dist_mm)) < 110.0


def _check_video(msgs: dict, rec: Path) -> None:
    from vision.recording import PadRecording

    images = msgs["/fydpad/camera/image_raw/compressed"]
    pr = PadRecording(rec)
    assert len(images) == pr.frame_count
    for k, ((t_log, msg), (_, t_s, frame)) in enumerate(zip(images, pr.frames(), strict=True)):
        assert t_log == _stamp_ns(msg.header) == _ns(t_s)
        assert msg.format == "jpeg"
        if k % 10:
            continue  # the pixels of every tenth frame (the time above is every frame's)
        ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 90])
        assert ok and bytes(msg.data) == jpeg.tobytes()
        decoded = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
        assert decoded.shape == frame.shape
        assert float(np.abs(decoded.astype(int) - frame).mean()) < 3.0  # JPEG at quality 90


def _check_metadata(bag: Path, msgs: dict) -> None:
    """metadata.yaml against the keys rosbag2's storage reader decodes (format version 9)."""
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    for key in ("duration", "starting_time", "message_count", "topics_with_message_count",
                "compression_format", "compression_mode", "relative_file_paths", "files",
                "custom_data", "ros_distro"):
        assert key in info, key
    assert info["message_count"] == sum(len(v) for v in msgs.values())
    (mcap,) = bag.glob("*.mcap")
    assert info["relative_file_paths"] == [mcap.name]
    assert info["files"][0]["path"] == mcap.name
    assert info["files"][0]["message_count"] == info["message_count"]
    times = [t for v in msgs.values() for t, _ in v]
    assert info["starting_time"]["nanoseconds_since_epoch"] == min(times)
    assert info["duration"]["nanoseconds"] == max(times) - min(times)
    for entry in info["topics_with_message_count"]:
        meta = entry["topic_metadata"]
        assert set(meta) >= {"name", "type", "serialization_format", "offered_qos_profiles",
                             "type_description_hash"}
        assert meta["type"] == TOPICS[meta["name"]]
        assert meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"].startswith("RIHS01_")
        assert isinstance(meta["offered_qos_profiles"], list)  # version 9: a list, not text
        assert entry["message_count"] == len(msgs[meta["name"]])
    tf = next(e for e in info["topics_with_message_count"]
              if e["topic_metadata"]["name"] == "/tf_static")["topic_metadata"]
    assert tf["offered_qos_profiles"][0]["durability"] == "transient_local"


def _check_tf(msgs: dict, rec: Path) -> None:
    ((t_tf, tf),) = msgs["/tf_static"]
    assert t_tf == 0
    frames = {(x.header.frame_id, x.child_frame_id): x.transform for x in tf.transforms}
    ws = frames[("base_link", "fydpad_workspace")]
    origin = load_config(DEVICE).teleop.mapping.origin_mm
    assert (ws.translation.x, ws.translation.y, ws.translation.z) == tuple(
        v / 1000.0 for v in origin)
    meta = read_meta(rec)
    for j, (x, y) in enumerate(meta.ir_sensors_mm):
        tr = frames[("fydpad_workspace", f"fydpad_ir{j}")].translation
        assert (tr.x, tr.y, tr.z) == (x / 1000.0, y / 1000.0, -meta.base_to_fabric_mm / 1000.0)
        q = frames[("fydpad_workspace", f"fydpad_ir{j}")].rotation
        # The Range's x axis (its beam) turned to +z: up at the fabric.
        from scipy.spatial.transform import Rotation

        beam = Rotation.from_quat([q.x, q.y, q.z, q.w]).apply([1.0, 0.0, 0.0])
        np.testing.assert_allclose(beam, [0.0, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_recording_reads_back_equal(name, tmp_path):
    rec = _copy_with_track(name, tmp_path)
    bag = tmp_path / "bag"
    summary = export_bag(rec, bag, load_config(DEVICE), video=name == "circle")
    msgs = _read_bag(bag)
    assert summary.counts == {k: len(v) for k, v in msgs.items()}
    _check_finger(msgs, rec, "track.csv", "/fydpad/finger")
    _check_finger(msgs, rec, "truth.csv", "/fydpad/finger/truth")
    _check_sensors(msgs, rec)
    _check_tf(msgs, rec)
    _check_metadata(bag, msgs)
    if name == "circle":
        _check_video(msgs, rec)
    for topic, got in msgs.items():
        assert [t for t, _ in got] == sorted(t for t, _ in got), topic


def test_vibration_and_slave_log_read_back_equal(tmp_path):
    """A 1 kHz commands.csv (the render loop's log, negative times before the first frame
    included) and a slave log from a real tele-operation pass (PyBullet slave, loopback)."""
    from fydpad.export.slave_log import read_slave_log, write_slave_log
    from teleop.config import TeleopConfig
    from teleop.master import run_local_sim
    from vision.state import FingerState

    rec = _copy_with_track("circle", tmp_path)
    t = np.arange(-5, 3000) / 1000.0
    vib = np.round(0.3 * np.sin(2 * np.pi * 180.0 * t), 6)
    with (rec / "commands.csv").open("w") as fh:
        fh.write("t_s,frame,vibration,duty0,duty1,theta_ref_rad\n")
        for ti, v in zip(t, vib, strict=True):
            fh.write(f"{ti:.6f},0,{v:.6f},0,0,0\n")
    truth = read_csv_columns(rec / "truth.csv", ("t_s", "contact", "x_mm", "y_mm",
                                                 "indentation_mm"), empty_ok=("x_mm", "y_mm"))
    keep = (truth["t_s"] >= 2.4) & (truth["t_s"] < 3.4)
    states = [FingerState(float(ts), bool(c), x, y, d) if c else FingerState.no_contact(ts)
              for ts, c, x, y, d in zip(truth["t_s"][keep], truth["contact"][keep],
                                        truth["x_mm"][keep], truth["y_mm"][keep],
                                        truth["indentation_mm"][keep], strict=True)]
    cfg = TeleopConfig()
    cfg.link.rt_priority = 0
    session = run_local_sim(states, cfg, baseline=False)
    write_slave_log(session, rec / "slave.csv")
    log = read_slave_log(rec / "slave.csv")
    assert log["t_s"].size > 200  # 500 Hz ticks over about a second
    bag = tmp_path / "bag"
    summary = export_bag(rec, bag, load_config(DEVICE), video=False)
    assert summary.before_start == 5
    msgs = _read_bag(bag)
    got = msgs["/fydpad/vibration"]
    assert [ts for ts, _ in got] == [_ns(x) for x in t[t >= 0]]
    assert [m.data for _, m in got] == list(vib[t >= 0])
    for kind, col in (("command_pose", "cmd"), ("actual_pose", "actual")):
        poses = [(ts, m) for ts, m in msgs[f"/fydpad/slave/{kind}"]]
        ok = log["t_s"] >= 0
        assert len(poses) == int(ok.sum())
        for (ts, m), tr, x, y, z in zip(poses, log["t_s"][ok], log[f"{col}_x_mm"][ok],
                                        log[f"{col}_y_mm"][ok], log[f"{col}_z_mm"][ok],
                                        strict=True):
            assert ts == _ns(tr)
            p = m.pose.position
            assert (p.x, p.y, p.z) == (x / 1000.0, y / 1000.0, -z / 1000.0)
    # The slave followed the finger: its actual position near the true one while touching.
    act = np.column_stack([log["actual_x_mm"], log["actual_y_mm"]])
    on = truth["contact"][keep] != 0
    tt = truth["t_s"][keep][on]
    ax = np.interp(tt, log["t_s"], act[:, 0])
    assert float(np.median(np.abs(ax - truth["x_mm"][keep][on]))) < 3.0


def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys):
    assert main(["export", "bag", str(tmp_path / "nope"), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a directory" in err[0] and "nope" in err[0]
    rec = tmp_path / "rec"
    rec.mkdir()
    assert main(["export", "bag", str(rec), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "meta.json: missing" in err[0]
    rec2 = _copy_with_track("tapping", tmp_path)
    (rec2 / "force.csv").write_text("t_s,force_n\n0,0.1\n0.01,oops\n")
    out = tmp_path / "b2"
    assert main(["export", "bag", str(rec2), "--out", str(out), "--no-video"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "force.csv" in err[0] and "line 3" in err[0]
    assert not out.exists()  # nothing half-written
    assert main(["export", "bag", str(rec2), "--out", str(rec2)]) == 2
    assert "already exists" in capsys.readouterr().err


def test_cli_tracks_the_video_without_track_csv(tmp_path, capsys):
    """No track.csv: the command tracks the video as `fydpad track` does."""
    rec = tmp_path / "rec"
    shutil.copytree(RECORDINGS / "tapping", rec)
    bag = tmp_path / "bag"
    assert main(["export", "bag", str(rec), "--out", str(bag), "--no-video",
                 "--config", str(DEVICE)]) == 0
    assert "messages" in capsys.readouterr().out
    msgs = _read_bag(bag)
    truth = read_csv_columns(rec / "truth.csv", ("t_s", "contact", "x_mm", "y_mm"),
                             empty_ok=("x_mm", "y_mm"))
    contact = np.array([m.data for _, m in msgs["/fydpad/finger/contact"]])
    assert contact.size == truth["t_s"].size
    assert float(np.mean(contact == (truth["contact"] != 0))) > 0.9
    poses = {t: m.pose.position for t, m in msgs["/fydpad/finger/pose"]}
    on = [k for k, t in enumerate(truth["t_s"]) if _ns(t) in poses and truth["contact"][k]]
    err = [math.hypot(poses[_ns(truth["t_s"][k])].x * 1000 - truth["x_mm"][k],
                      poses[_ns(truth["t_s"][k])].y * 1000 - truth["y_mm"][k]) for k in on]
    assert len(on) > 20 and float(np.median(err)) < 2.0
