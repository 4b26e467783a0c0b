"""A tiny RTDE protocol server (Universal Robots' Real-Time Data Exchange, port 30004):
enough for ur-rtde's RTDEReceiveInterface to connect and read poses.

Messages: big-endian header (uint16 size incl. header, uint8 type), then the payload.
Handled: request protocol version ('V'), get controller version ('v'), setup outputs
('O': frequency f64 + comma-separated names -> recipe id + comma-separated types),
setup inputs ('I'), start ('S'), pause ('P'); after start, data packages ('U': recipe id
+ values) at the requested frequency. Types follow UR's RTDE guide.
"""

from __future__ import annotations

import socket
import struct
import threading
import time

V, v, O, I, S, P, U = (ord(c) for c in "VvOISPU")  # noqa: E741

TYPES = {
    "VECTOR6D": ">6d", "VECTOR3D": ">3d", "DOUBLE": ">d", "UINT64": ">Q", "UINT32": ">I",
    "INT32": ">i", "VECTOR6INT32": ">6i", "VECTOR6UINT32": ">6I", "UINT8": ">B", "BOOL": ">?",
}
V6 = {"target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
      "actual_qd", "actual_current", "joint_control_output", "actual_TCP_pose",
      "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose", "target_TCP_speed",
      "joint_temperatures", "actual_joint_voltage", "ft_raw_wrench", "payload_inertia",
      "actual_current_window", "actual_current_as_torque", "tcp_offset"}
V3 = {"actual_tool_accelerometer", "elbow_position", "elbow_velocity", "payload_cog"}
U64 = {"actual_digital_input_bits", "actual_digital_output_bits"}
U32 = {"robot_status_bits", "safety_status_bits", "runtime_state", "analog_io_types",
       "output_bit_registers0_to_31", "output_bit_registers32_to_63",
       "input_bit_registers0_to_31", "input_bit_registers32_to_63"}
I32 = {"robot_mode", "safety_mode", "safety_status", "tool_mode", "tool_output_voltage"}
U8 = {"tool_analog_input_types", "tool_output_mode", "tool_digital_output0_mode",
      "tool_digital_output1_mode"}


def rtde_type(name: str) -> str:
    if name in V6:
        return "VECTOR6D"
    if name in V3:
        return "VECTOR3D"
    if name in U64:
        return "UINT64"
    if name in U32:
        return "UINT32"
    if name in I32 or name.startswith(("output_int_register", "input_int_register")):
        return "INT32"
    if name in U8:
        return "UINT8"
    if name == "joint_mode":
        return "VECTOR6INT32"
    if name.startswith(("output_bit_register_", "input_bit_register_")):
        return "BOOL"
    return "DOUBLE"


class RTDEServer:
    """Serves one client at a time; ``pose`` is what actual_TCP_pose reports."""

    def __init__(self, host: str = "127.0.0.2", port: int = 30004,
                 version: tuple[int, int, int, int] = (5, 11, 0, 0)) -> None:
        self.pose = [0.55, -0.01, 0.25, 0.0, 3.14159, 0.0]
        self.version = version
        self.requested: list[str] = []
        self.log: list[str] = []
        self.srv = socket.socket()
        self.srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.srv.bind((host, port))  # OSError if taken: the test skips
        self.srv.listen(2)
        self.srv.settimeout(0.2)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self) -> RTDEServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(3)
        self.srv.close()

    @staticmethod
    def _send(conn: socket.socket, typ: int, payload: bytes) -> None:
        conn.sendall(struct.pack(">HB", 3 + len(payload), typ) + payload)

    @staticmethod
    def _recv_exact(conn: socket.socket, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = conn.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("client closed")
            buf += chunk
        return buf

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.srv.accept()
            except TimeoutError:
                continue
            try:
                self._session(conn)
            except (ConnectionError, OSError):
                pass
            finally:
                conn.close()

    def _session(self, conn: socket.socket) -> None:
        conn.settimeout(0.01)
        names: list[str] = []
        period = 0.002
        started = False
        t_next = time.monotonic()
        while not self._stop.is_set():
            try:
                size, typ = struct.unpack(">HB", self._recv_exact(conn, 3))
                conn.settimeout(1.0)
                body = self._recv_exact(conn, size - 3)
                conn.settimeout(0.01)
            except TimeoutError:
                body, typ = None, None
            if typ is not None:
                self.log.append(chr(typ))
            if typ == V:
                self._send(conn, V, b"\x01")
            elif typ == v:
                self._send(conn, v, struct.pack(">IIII", *self.version))
            elif typ == O:
                freq = struct.unpack(">d", body[:8])[0]
                period = 1.0 / freq if freq > 0 else 0.002
                names = [n for n in body[8:].decode().split(",") if n]
                self.requested = names
                types = ",".join(rtde_type(n) for n in names)
                self._send(conn, O, b"\x01" + types.encode())
            elif typ == I:
                in_names = [n for n in body.decode().split(",") if n]
                self._send(conn, I, b"\x02" + ",".join(rtde_type(n) for n in in_names).encode())
            elif typ == S:
                started = True
                self._send(conn, S, b"\x01")
            elif typ == P:
                started = False
                self._send(conn, P, b"\x01")
            if started and time.monotonic() >= t_next:
                t_next = time.monotonic() + period
                payload = b"\x01"
                for n in names:
                    t = rtde_type(n)
                    if n == "actual_TCP_pose":
                        payload += struct.pack(TYPES[t], *self.pose)
                    elif n == "timestamp":
                        payload += struct.pack(">d", time.monotonic())
                    elif n == "robot_mode":
                        payload += struct.pack(">i", 7)  # RUNNING
                    elif n == "safety_mode":
                        payload += struct.pack(">i", 1)  # NORMAL
                    else:
                        k = struct.calcsize(TYPES[t])
                        payload += bytes(k)
                self._send(conn, U, payload)
