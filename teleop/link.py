"""ZeroMQ sockets of the link, with CurveZMQ when the endpoint leaves the machine.

Pattern (docs/protocol.md): the slave binds a ROUTER, the master connects a DEALER.
One socket each way carries samples and states, several masters can reconnect, and
the slave answers whoever sent the last sample. A stale sample never waits behind a
fresh one: the master's queue is in order, bounded (``send_hwm``) and refuses to queue
for an absent peer (ZMQ_IMMEDIATE); the slave drains everything readable each tick, drops
what aged past ``safety.max_age_s`` and acts on the newest sample only.
"""

from __future__ import annotations

import ipaddress
import logging
import select
import time
from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlparse

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from teleop.config import LinkConfig
from teleop.keys import client_keys, server_keys

log = logging.getLogger(__name__)


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

    def close(self) -> None:
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
