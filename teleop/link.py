"""ZeroMQ sockets of the link, with CurveZMQ when the endpoint leaves the machine.

Pattern (docs/protocol.md): the slave binds a ROUTER, the master connects a DEALER.
One socket each way carries samples and states. Each master socket has its own random
routing id, so a reconnect is the same master; one master owns the arm at a time
(teleop/admission.py). Both sockets refuse messages over MAX_MSG_SIZE; the slave counts
refused CurveZMQ handshakes from its socket monitor. A stale sample never waits behind a
fresh one: the master's queue is in order, bounded (``send_hwm``) and refuses to queue
for an absent peer (ZMQ_IMMEDIATE); the slave drains everything readable each tick, drops
what aged past ``safety.max_age_s`` and acts on the newest sample only.
"""

from __future__ import annotations

import ipaddress
import logging
import math
import os
import select
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlparse

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator
from zmq.utils.monitor import recv_monitor_message

from teleop.config import LinkConfig
from teleop.keys import client_keys, server_keys

log = logging.getLogger(__name__)

# ZMQ_MAXMSGSIZE on both sockets (docs/protocol.md): the largest message is a state (96
# bytes), CURVE's handshake commands stay under 400; a peer sending more is disconnected by
# libzmq from the length in the frame header, before any of it is read into memory.
MAX_MSG_SIZE = 4096

# Socket-monitor events of a refused handshake. ZAP (the authenticator) sees only clients
# that completed the CURVE exchange; these see every refusal.
_HANDSHAKE_EVENTS = (zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL | zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL
                     | zmq.EVENT_HANDSHAKE_FAILED_AUTH)
HANDSHAKE_HINTS = {
    "no_keys": "a client without CurveZMQ keys (or with keys, to a slave without)",
    "wrong_server_key": "a client holding the wrong server.key",
    "unknown_client_key": "a client key not in authorized_clients/",
    "protocol_error": "a peer speaking another protocol",
    "no_detail": "the connection failed during the handshake",
}
HANDSHAKE_LOG_EVERY_S = 10.0  # one line per kind at most this often, with the running count


def handshake_failure_kind(event: int, value: int) -> str:
    """The name a refused handshake is counted under (HANDSHAKE_HINTS)."""
    if event == zmq.EVENT_HANDSHAKE_FAILED_AUTH:
        return "unknown_client_key"
    if event == zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL:
        if value == zmq.PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH:
            return "no_keys"
        if value == zmq.PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC:
            return "wrong_server_key"
        return "protocol_error"
    return "no_detail"


# The monitor's value for a protocol failure, by name (for auth it is the ZAP status, 400).
_PROTOCOL_ERRORS = {getattr(zmq, n): n for n in dir(zmq) if n.startswith("PROTOCOL_ERROR_")}


def master_routing_id() -> bytes:
    """A routing id unique to this master socket, random at its creation: a TCP reconnect
    keeps it, so the slave sees the same master; a new process is a new master. 16 bytes,
    the first never 0 (libzmq reserves ids starting with a zero byte)."""
    return b"M" + os.urandom(15)


def is_loopback(endpoint: str) -> bool:
    """True for ipc/inproc and tcp to 127.0.0.0/8, ::1 or localhost."""
    if endpoint.startswith(("ipc://", "inproc://")):
        return True
    host = urlparse(endpoint.replace("tcp://", "tcp://", 1)).hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name or interface: assume it leaves the machine


def wait_readable(sock: zmq.Socket, t_end_s: float, clock: Callable[[], float]) -> bool:
    """Wait until ``sock`` has a message (True) or the clock reaches ``t_end_s`` (False).

    zmq_poll counts whole milliseconds and pyzmq truncates a float timeout, so waiting
    0.7 ms with it is a busy loop: at 1 kHz the master spun a whole core and the slave
    (2 ms ticks) half of one, which on a loaded machine delays the very threads that move
    the messages. Here the socket's signalling descriptor (edge-triggered: ZMQ_EVENTS is
    checked before each wait) is waited on with select(), to the microsecond.
    """
    fd = sock.getsockopt(zmq.FD)
    while True:
        if sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:
            return True
        remaining = t_end_s - clock()
        if remaining <= 0:
            return False
        select.select([fd], [], [], remaining)


def tcp_endpoint(endpoint: str) -> str:
    """``HOST:PORT`` as ``tcp://HOST:PORT``; an endpoint with a transport is kept as is."""
    return endpoint if "://" in endpoint else f"tcp://{endpoint}"


def curve_enabled(cfg: LinkConfig, endpoint: str) -> bool:
    if cfg.curve not in ("auto", "on", "off"):
        raise ValueError(f"link.curve must be 'auto', 'on' or 'off', got {cfg.curve!r}")
    return cfg.curve == "on" or (cfg.curve == "auto" and not is_loopback(endpoint))


class LoggingAuthenticator(ThreadAuthenticator):
    """ZAP handler that logs and counts refused clients (the default only logs at debug)."""

    denied = 0

    async def _authenticate_curve(self, domain: str, client_key: bytes) -> tuple[bool, bytes]:
        allowed, reason = await super()._authenticate_curve(domain, client_key)
        if not allowed:
            type(self).denied += 1
            log.warning("refused a client with an unknown CURVE key %s (%s): add its public "
                        "key to authorized_clients/ to allow it",
                        zmq.utils.z85.encode(client_key).decode(), reason.decode())
        return allowed, reason


def _start_authenticator(auth: ThreadAuthenticator, timeout_s: float = 2.0) -> None:
    """Start the ZAP handler, waiting while its endpoint is still held.

    A context has one ZAP endpoint (inproc://zeromq.zap.01). The previous authenticator's
    socket frees it only when libzmq's reaper thread destroys that socket, after close()
    has returned: a slave restarted at once on the same context (the tests, a restart
    after a fault) could meet "Address already in use" under load (seen in CI)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            auth.start()
            return
        except zmq.ZMQError as e:
            if auth.zap_socket is not None:  # created, not bound: close it before retrying
                auth.zap_socket.close(linger=0)
                auth.zap_socket = None  # type: ignore[assignment]
            if e.errno != zmq.EADDRINUSE or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


class SlaveSocket:
    """The slave's bound ROUTER (+ authenticator). Context manager: always closes."""

    def __init__(self, endpoint: str, cfg: LinkConfig | None = None,
                 ctx: zmq.Context | None = None) -> None:
        cfg = cfg or LinkConfig()
        self.ctx = ctx or zmq.Context.instance()
        self.auth: LoggingAuthenticator | None = None
        self.sock = self.ctx.socket(zmq.ROUTER)
        self.sock.linger = 0
        self.sock.setsockopt(zmq.RCVHWM, 1000)
        self.sock.setsockopt(zmq.MAXMSGSIZE, MAX_MSG_SIZE)
        # A master reconnecting with its routing id takes it over at once (the old TCP
        # connection may not be seen dead yet); without this libzmq drops the new one.
        self.sock.setsockopt(zmq.ROUTER_HANDOVER, 1)
        self.handshakes_failed: Counter[str] = Counter()
        self._handshake_logged_s: dict[str, float] = {}
        self.monitor = self.sock.get_monitor_socket(_HANDSHAKE_EVENTS)
        self.curve = curve_enabled(cfg, endpoint)
        if self.curve:
            keys_dir = Path(cfg.keys_dir)
            pub, sec = server_keys(keys_dir)
            self.auth = LoggingAuthenticator(self.ctx)
            _start_authenticator(self.auth)
            self.auth.configure_curve(domain="*", location=str(keys_dir / "authorized_clients"))
            self.sock.curve_secretkey = sec
            self.sock.curve_publickey = pub
            self.sock.curve_server = True
        try:
            self.sock.bind(endpoint)
        except zmq.ZMQError as e:
            self.close()
            raise OSError(f"slave cannot bind {endpoint}: {e}") from e
        self.endpoint = self.sock.getsockopt_string(zmq.LAST_ENDPOINT)

    def poll_monitor(self) -> int:
        """Count and log every refused handshake the socket monitor reported (non-blocking;
        the slave calls it each tick). Refusals that never reach ZAP (a client without keys,
        or with the wrong server key) are seen only here. Returns how many were read."""
        n = 0
        while True:
            try:
                ev = recv_monitor_message(self.monitor, zmq.NOBLOCK)
            except zmq.ZMQError:  # Again: none waiting; or the monitor is closed
                return n
            if not int(ev["event"]) & _HANDSHAKE_EVENTS:
                continue
            n += 1
            value = int(ev["value"])
            kind = handshake_failure_kind(int(ev["event"]), value)
            self.handshakes_failed[kind] += 1
            now = time.monotonic()
            if now - self._handshake_logged_s.get(kind, -math.inf) >= HANDSHAKE_LOG_EVERY_S:
                self._handshake_logged_s[kind] = now
                log.warning("refused a CurveZMQ handshake on %s: %s (%s, code %s; %d refused "
                            "so far)", self.endpoint, HANDSHAKE_HINTS[kind], kind,
                            _PROTOCOL_ERRORS.get(value, value), self.handshakes_failed[kind])

    def close(self) -> None:
        try:
            self.sock.disable_monitor()
        except zmq.ZMQError:
            pass
        self.monitor.close(linger=0)
        self.sock.close(linger=0)
        if self.auth is not None:
            self.auth.stop()
            self.auth = None

    def __enter__(self) -> SlaveSocket:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class MasterSocket:
    """The master's DEALER. Context manager: always closes."""

    def __init__(self, endpoint: str, cfg: LinkConfig | None = None,
                 ctx: zmq.Context | None = None) -> None:
        cfg = cfg or LinkConfig()
        endpoint = tcp_endpoint(endpoint)
        keys = None
        if curve_enabled(cfg, endpoint):  # a missing key file fails before any socket
            keys_dir = Path(cfg.keys_dir)
            keys = client_keys(keys_dir), server_keys(keys_dir, public_only=True)[0]
        self.ctx = ctx or zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.DEALER)
        self.sock.linger = 0
        self.routing_id = master_routing_id()
        self.sock.setsockopt(zmq.ROUTING_ID, self.routing_id)
        self.sock.setsockopt(zmq.MAXMSGSIZE, MAX_MSG_SIZE)
        self.sock.sndhwm = cfg.send_hwm
        self.sock.setsockopt(zmq.IMMEDIATE, 1)  # never queue samples for a slave not there
        self.sock.setsockopt(zmq.RECONNECT_IVL, 50)
        self.sock.setsockopt(zmq.RECONNECT_IVL_MAX, 500)
        self.curve = keys is not None
        if keys is not None:
            (pub, sec), server_pub = keys
            self.sock.curve_publickey = pub
            self.sock.curve_secretkey = sec
            self.sock.curve_serverkey = server_pub
        try:
            self.sock.connect(endpoint)
        except zmq.ZMQError as e:
            self.close()
            raise OSError(f"master cannot connect to {endpoint}: {e}") from e
        self.endpoint = endpoint

    def send(self, data: bytes) -> bool:
        """Non-blocking send; False when the slave is absent or the queue is full."""
        try:
            self.sock.send(data, zmq.NOBLOCK)
            return True
        except zmq.Again:
            return False

    def close(self) -> None:
        self.sock.close(linger=0)

    def __enter__(self) -> MasterSocket:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
