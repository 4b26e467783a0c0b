"""A pad session recording as a ROS 2 bag (rosbag2, MCAP storage), written with the pure
Python ``rosbags`` library (``pip install fydpad[ros]``). Topics and conventions:
docs/ros.md.

Frames follow ROS REP 103 (metres, right-handed): ``fydpad_workspace`` has x to the user's
right, y away from the user, z up out of the fabric, so a finger indenting the fabric by
d mm sits at z = -d/1000 m. ``base_link`` is the robot's base; the static transform
between them is the tele-operation mapping (``[teleop.mapping]`` origin and orientation).
Every message is stamped with the recording's own clock (``t_s`` from its start).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from fydpad.config import StationConfig
from fydpad.errors import UserError
from fydpad.export.slave_log import read_slave_log
from teleop.mapping import rpy_matrix
from vision.indentation import IndentationEstimator
from vision.recording import (
    PadRecording,
    RecordingError,
    find_video,
    read_csv_columns,
    read_meta,
    read_track,
)

WORKSPACE_FRAME = "fydpad_workspace"
ROBOT_BASE_FRAME = "base_link"
CAMERA_FRAME = "fydpad_camera"
IR_FRAMES = ("fydpad_ir0", "fydpad_ir1", "fydpad_ir2")

#: topic -> ROS 2 message type (docs/ros.md lists what each carries).
TOPICS = {
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/fydpad/finger/pose": "geometry_msgs/msg/PoseStamped",
    "/fydpad/finger/contact": "std_msgs/msg/Bool",
    "/fydpad/finger/indentation_mm": "std_msgs/msg/Float64",
    "/fydpad/finger/truth/pose": "geometry_msgs/msg/PoseStamped",
    "/fydpad/force": "geometry_msgs/msg/WrenchStamped",
    "/fydpad/camera/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
    "/fydpad/ir/volts": "std_msgs/msg/Float64MultiArray",
    "/fydpad/ir/range0": "sensor_msgs/msg/Range",
    "/fydpad/ir/range1": "sensor_msgs/msg/Range",
    "/fydpad/ir/range2": "sensor_msgs/msg/Range",
    "/fydpad/vibration": "std_msgs/msg/Float64",
    "/fydpad/slave/command_pose": "geometry_msgs/msg/PoseStamped",
    "/fydpad/slave/actual_pose": "geometry_msgs/msg/PoseStamped",
}

#: The IR sensors' usable span (sensor_msgs/Range min_range, max_range): the Sharp
#: GP2Y0A41SK0F the paper uses reads 4-30 cm.
IR_RANGE_M = (0.04, 0.30)
IR_FIELD_OF_VIEW_RAD = 0.1
JPEG_QUALITY = 90


def stamp_ns(t_s: float) -> int:
    """Nanoseconds of the recording's clock (the bag's log time and header stamps)."""
    return round(t_s * 1e9)


@dataclass
class BagSummary:
    """What an export wrote: message count per topic, the bag directory."""

    path: Path
    counts: dict[str, int] = field(default_factory=dict)
    #: Samples stamped before the recording's t_s = 0 (MCAP times are unsigned), left out.
    before_start: int = 0

    @property
    def messages(self) -> int:
        return sum(self.counts.values())


@dataclass
class RecordingFiles:
    """The files of RECDIR an export reads (each optional except meta.json)."""

    recdir: Path
    track: Path | None = None
    slave_log: Path | None = None

    def __post_init__(self) -> None:
        if not self.recdir.is_dir():
            raise UserError(f"{self.recdir}: not a directory (expected a pad session recording)")
        if not (self.recdir / "meta.json").is_file():
            raise UserError(f"{self.recdir / 'meta.json'}: missing (every pad session "
                            "recording has one)")
        if self.track is None and (self.recdir / "track.csv").is_file():
            self.track = self.recdir / "track.csv"
        if self.slave_log is None and (self.recdir / "slave.csv").is_file():
            self.slave_log = self.recdir / "slave.csv"
        for p in (self.track, self.slave_log):
            if p is not None and not p.is_file():
                raise UserError(f"{p}: missing")

    def optional(self, name: str) -> Path | None:
        p = self.recdir / name
        return p if p.is_file() else None


def _quat_from_matrix(m: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix."""
    x, y, z, w = Rotation.from_matrix(m).as_quat()
    return float(x), float(y), float(z), float(w)


class _Bag:
    """A rosbags Writer with one connection per topic and a message count per topic."""

    def __init__(self, path: Path) -> None:
        # rosbags: the optional extra ``ros``, checked by require_rosbags before export
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        # Uncompressed: rosbag2's message compression wraps each payload in zstd, which
        # only rosbag2 itself undoes (Foxglove, Rerun and the mcap readers cannot decode it).
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.conns: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.before_start = 0
        self.T = self.ts.types

    def __enter__(self) -> _Bag:
        self.writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(self, topic: str, t_s: float, msg: Any) -> None:
        if t_s < 0:  # before the first frame (the render loop starts first): no bag time
            self.before_start += 1
            return
        conn = self.conns.get(topic)
        if conn is None:
            conn = self.conns[topic] = self.writer.add_connection(
                topic, TOPICS[topic], typestore=self.ts,
                offered_qos_profiles=[_latched_qos()] if topic == "/tf_static" else ())
            self.counts[topic] = 0
        self.writer.write(conn, stamp_ns(t_s), self.ts.serialize_cdr(msg, TOPICS[topic]))
        self.counts[topic] += 1

    # -- message builders -----------------------------------------------------------
    def header(self, t_s: float, frame_id: str) -> Any:
        ns = stamp_ns(t_s)
        return self.T["std_msgs/msg/Header"](
            stamp=self.T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                        nanosec=ns % 1_000_000_000),
            frame_id=frame_id)

    def pose(self, t_s: float, frame_id: str, xyz_m: tuple[float, float, float],
             quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)) -> Any:
        T = self.T
        return T["geometry_msgs/msg/PoseStamped"](
            header=self.header(t_s, frame_id),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=xyz_m[0], y=xyz_m[1], z=xyz_m[2]),
                orientation=T["geometry_msgs/msg/Quaternion"](
                    x=quat[0], y=quat[1], z=quat[2], w=quat[3])))

    def float64(self, v: float) -> Any:
        return self.T["std_msgs/msg/Float64"](data=float(v))


def _latched_qos() -> Any:
    """/tf_static's QoS as tf2 publishes it (transient local, reliable, keep last 1), so
    ``ros2 bag play`` offers it latched and late subscribers still get the frames."""
    from rosbags.interfaces import (  # the optional extra ``ros``
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    never = QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF)
    return Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
               never, never, QosLiveliness.AUTOMATIC, never, False)


def _workspace_m(x_mm: float, y_mm: float, indentation_mm: float) -> tuple[float, float, float]:
    """Workspace (x, y, indentation) mm -> fydpad_workspace (x, y, z up) m."""
    return x_mm / 1000.0, y_mm / 1000.0, -indentation_mm / 1000.0


def _write_tf(bag: _Bag, config: StationConfig) -> list[Any]:
    """base_link -> fydpad_workspace (the mapping), fydpad_workspace -> each IR sensor."""
    T = bag.T
    m = config.teleop.mapping
    rot = rpy_matrix(*m.rpy_deg)
    if m.reflect_x:  # the workspace's x mirrored: a rotation of pi about y is not it; say so
        raise UserError("export bag: mapping.reflect_x mirrors the workspace, which no tf "
                        "transform can express; export with reflect_x = false")

    def transform(parent: str, child: str, xyz_m, quat) -> Any:
        return T["geometry_msgs/msg/TransformStamped"](
            header=bag.header(0.0, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=xyz_m[0], y=xyz_m[1], z=xyz_m[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](
                    x=quat[0], y=quat[1], z=quat[2], w=quat[3])))

    origin_m = [v / 1000.0 for v in m.origin_mm]
    tfs = [transform(ROBOT_BASE_FRAME, WORKSPACE_FRAME, origin_m, _quat_from_matrix(rot))]
    return tfs


def _ir_transforms(bag: _Bag, sensors_mm, base_to_fabric_mm: float) -> list[Any]:
    """Each IR sensor under the fabric, looking up (+z: a Range's x axis along +z)."""
    T = bag.T
    up = (0.0, -math.sqrt(0.5), 0.0, math.sqrt(0.5))  # rotation of -90 deg about y: x -> +z
    out = []
    for name, (x, y) in zip(IR_FRAMES, sensors_mm, strict=True):
        out.append(T["geometry_msgs/msg/TransformStamped"](
            header=bag.header(0.0, WORKSPACE_FRAME), child_frame_id=name,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](
                    x=x / 1000.0, y=y / 1000.0, z=-base_to_fabric_mm / 1000.0),
                rotation=T["geometry_msgs/msg/Quaternion"](
                    x=up[0], y=up[1], z=up[2], w=up[3]))))
    return out


def _finger_rows(files: RecordingFiles, config: StationConfig,
                 track_video: Callable[[], dict[str, NDArray[np.float64]]] | None
                 ) -> dict[str, NDArray[np.float64]] | None:
    if files.track is not None:
        return read_track(files.track)
    return track_video() if track_video is not None else None


def _frames(recdir: Path) -> Iterator[tuple[float, NDArray[np.uint8]]]:
    rec = PadRecording(recdir)
    for _, t_s, frame in rec.frames():
        yield t_s, frame


def export_bag(recdir: str | Path, out: str | Path, config: StationConfig | None = None, *,
               track: str | Path | None = None, slave_log: str | Path | None = None,
               video: bool = True,
               track_video: Callable[[], dict[str, NDArray[np.float64]]] | None = None,
               ) -> BagSummary:
    """Write the recording at ``recdir`` as a rosbag2 (MCAP) directory ``out``.

    ``track``: tracking output CSV (default RECDIR/track.csv, as ``fydpad run --record``
    writes it); without one, ``track_video()`` supplies its columns (the command tracks
    the video). ``slave_log``: the slave's command and actual position (default
    RECDIR/slave.csv). ``out`` must not exist (rosbag2 refuses to overwrite a bag).
    """
    config = config or StationConfig()
    files = RecordingFiles(Path(recdir), Path(track) if track else None,
                           Path(slave_log) if slave_log else None)
    out = Path(out)
    if out.exists():
        raise UserError(f"{out}: already exists (a bag is written to a new directory)")
    try:
        meta = read_meta(files.recdir)
        finger = _finger_rows(files, config, track_video)
    except RecordingError as exc:
        raise UserError(str(exc)) from None
    bag = _Bag(out)
    tfs = _write_tf(bag, config) + _ir_transforms(bag, meta.ir_sensors_mm,
                                                 meta.base_to_fabric_mm)
    events: list[tuple[float, int, str, Any]] = []  # every file read before the bag opens
    try:
        _finger_events(bag, finger, events, "/fydpad/finger")
        _truth_events(bag, files, events)
        _force_events(bag, files, events)
        _ir_events(bag, files, meta, config, events)
        _vibration_events(bag, files, events)
        _slave_events(bag, files, events)
    except RecordingError as exc:
        raise UserError(str(exc)) from None
    events.sort(key=lambda e: (e[0], e[1]))
    video_path = _video_path(files.recdir) if video else None
    try:
        with bag:
            bag.write("/tf_static", 0.0, bag.T["tf2_msgs/msg/TFMessage"](transforms=tfs))
            frames = _frames(files.recdir) if video_path is not None else iter(())
            _write_merged(bag, events, frames)
    except (RecordingError, UserError) as exc:
        shutil.rmtree(out, ignore_errors=True)  # no half bag left behind
        raise UserError(str(exc)) from None
    return BagSummary(out, dict(bag.counts), bag.before_start)


def _video_path(recdir: Path) -> Path | None:
    try:
        return find_video(recdir)
    except RecordingError:
        return None


def _write_merged(bag: _Bag, events: list[tuple[float, int, str, Any]],
                  frames: Iterator[tuple[float, NDArray[np.uint8]]]) -> None:
    """Messages in time order, the video's frames encoded as they come (one in memory)."""
    T = bag.T
    i = 0
    for t_f, frame in frames:
        while i < len(events) and events[i][0] <= t_f:
            bag.write(events[i][2], events[i][0], events[i][3])
            i += 1
        ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            raise UserError(f"frame at t_s={t_f:.6f}: JPEG encoding failed")
        bag.write("/fydpad/camera/image_raw/compressed", t_f,
                  T["sensor_msgs/msg/CompressedImage"](
                      header=bag.header(t_f, CAMERA_FRAME), format="jpeg",
                      data=np.frombuffer(jpeg.tobytes(), np.uint8)))
    for t_s, _, topic, msg in events[i:]:
        bag.write(topic, t_s, msg)


def _finger_events(bag: _Bag, rows: dict[str, NDArray[np.float64]] | None,
                   events: list, prefix: str) -> None:
    if rows is None:
        return
    for k, t_s in enumerate(rows["t_s"]):
        t = float(t_s)
        contact = bool(rows["contact"][k] != 0)
        dent = float(rows["indentation_mm"][k])
        events.append((t, 0, f"{prefix}/contact", bag.T["std_msgs/msg/Bool"](data=contact)))
        if math.isfinite(dent):
            events.append((t, 1, f"{prefix}/indentation_mm", bag.float64(dent)))
        if contact:
            xyz = _workspace_m(float(rows["x_mm"][k]), float(rows["y_mm"][k]),
                               dent if math.isfinite(dent) else 0.0)
            events.append((t, 2, f"{prefix}/pose", bag.pose(t, WORKSPACE_FRAME, xyz)))


def _truth_events(bag: _Bag, files: RecordingFiles, events: list) -> None:
    p = files.optional("truth.csv")
    if p is None:
        return
    cols = read_csv_columns(p, ("t_s", "contact", "x_mm", "y_mm", "indentation_mm"),
                            empty_ok=("x_mm", "y_mm"))
    for k, t_s in enumerate(cols["t_s"]):
        if cols["contact"][k] != 0:
            t = float(t_s)
            xyz = _workspace_m(float(cols["x_mm"][k]), float(cols["y_mm"][k]),
                               float(cols["indentation_mm"][k]))
            events.append((t, 3, "/fydpad/finger/truth/pose", bag.pose(t, WORKSPACE_FRAME, xyz)))


def _force_events(bag: _Bag, files: RecordingFiles, events: list) -> None:
    p = files.optional("force.csv")
    if p is None:
        return
    T = bag.T
    cols = read_csv_columns(p, ("t_s", "force_n"))
    zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    for t_s, f_n in zip(cols["t_s"], cols["force_n"], strict=True):
        t = float(t_s)
        # The finger's push on the fabric: along -z of the workspace (into the pad).
        events.append((t, 4, "/fydpad/force", T["geometry_msgs/msg/WrenchStamped"](
            header=bag.header(t, WORKSPACE_FRAME),
            wrench=T["geometry_msgs/msg/Wrench"](
                force=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=-float(f_n)),
                torque=zero))))


def _ir_events(bag: _Bag, files: RecordingFiles, meta: Any, config: StationConfig,
               events: list) -> None:
    p = files.optional("ir.csv")
    if p is None:
        return
    T = bag.T
    cols = read_csv_columns(p, ("t_s", "v0", "v1", "v2"))
    volts = np.column_stack([cols["v0"], cols["v1"], cols["v2"]])
    est = IndentationEstimator.from_config(config.ir, sensors_mm=meta.ir_sensors_mm,
                                           baseline_mm=meta.ir_baseline_mm,
                                           base_to_fabric_mm=meta.base_to_fabric_mm)
    dist_mm, _flags = est.distances_mm(volts)
    layout = T["std_msgs/msg/MultiArrayLayout"](
        dim=[T["std_msgs/msg/MultiArrayDimension"](label="sensor", size=3, stride=3)],
        data_offset=0)
    for k, t_s in enumerate(cols["t_s"]):
        t = float(t_s)
        events.append((t, 5, "/fydpad/ir/volts", T["std_msgs/msg/Float64MultiArray"](
            layout=layout, data=volts[k].astype(np.float64))))
        for j in range(3):
            events.append((t, 6 + j, f"/fydpad/ir/range{j}", T["sensor_msgs/msg/Range"](
                header=bag.header(t, IR_FRAMES[j]), radiation_type=1,  # INFRARED
                field_of_view=IR_FIELD_OF_VIEW_RAD, min_range=IR_RANGE_M[0],
                max_range=IR_RANGE_M[1], range=float(dist_mm[k, j]) / 1000.0)))


def _vibration_events(bag: _Bag, files: RecordingFiles, events: list) -> None:
    p = files.optional("commands.csv")
    if p is None:
        return
    cols = read_csv_columns(p, ("t_s", "vibration"))
    for t_s, v in zip(cols["t_s"], cols["vibration"], strict=True):
        events.append((float(t_s), 9, "/fydpad/vibration", bag.float64(float(v))))


def _slave_events(bag: _Bag, files: RecordingFiles, events: list) -> None:
    if files.slave_log is None:
        return
    cols = read_slave_log(files.slave_log)
    for k, t_s in enumerate(cols["t_s"]):
        t = float(t_s)
        for kind, prefix in (("command_pose", "cmd"), ("actual_pose", "actual")):
            xyz = _workspace_m(float(cols[f"{prefix}_x_mm"][k]), float(cols[f"{prefix}_y_mm"][k]),
                               float(cols[f"{prefix}_z_mm"][k]))
            events.append((t, 10, f"/fydpad/slave/{kind}", bag.pose(t, WORKSPACE_FRAME, xyz)))
