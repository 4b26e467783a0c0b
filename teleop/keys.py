"""CurveZMQ key files for the link (`teleop keys generate DIR`).

Layout of DIR: server.key / server.key_secret (the slave), client.key /
client.key_secret (the master), authorized_clients/client.key (the public keys the
slave accepts; add other masters' *.key files there).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import zmq.auth

from vision.errors import UserError


def generate(keys_dir: Path) -> list[Path]:
    """Create a server and a client key pair and authorise the client; returns the files."""
    keys_dir = Path(keys_dir)
    keys_dir.mkdir(parents=True, exist_ok=True)
    for name in ("server", "client"):
        if (keys_dir / f"{name}.key_secret").exists():
            raise FileExistsError(f"{keys_dir / (name + '.key_secret')} exists: refusing to "
                                  "overwrite keys; remove the directory to regenerate")
    out = []
    for name in ("server", "client"):
        pub, sec = zmq.auth.create_certificates(keys_dir, name)
        Path(sec).chmod(0o600)
        out += [Path(pub), Path(sec)]
    auth = keys_dir / "authorized_clients"
    auth.mkdir(exist_ok=True)
    shutil.copy(keys_dir / "client.key", auth / "client.key")
    out.append(auth / "client.key")
    return out


class KeyFileMissing(UserError, FileNotFoundError):
    """A CurveZMQ key file is not where the link looks; the message says which command
    makes it and where it goes."""


#: The files the master needs, copied from the slave's key directory.
MASTER_FILES = ("server.key", "client.key", "client.key_secret")


def _load(path: Path, public_only: bool, hint: str) -> tuple[bytes, bytes]:
    if not path.exists():
        raise KeyFileMissing(f"CurveZMQ key file {path} not found: {hint}")
    pub, sec = zmq.auth.load_certificate(path)
    if not public_only and sec is None:
        raise ValueError(f"{path} has no secret key")
    return pub, sec or b""


def server_keys(keys_dir: Path, public_only: bool = False) -> tuple[bytes, bytes]:
    """The slave's pair (its secret key stays on the slave), or only its public key."""
    name = "server.key" if public_only else "server.key_secret"
    hint = (_master_hint(keys_dir) if public_only else
            f"run `teleop keys generate {keys_dir}` on the slave (or give --keys DIR)")
    return _load(Path(keys_dir) / name, public_only, hint)


def client_keys(keys_dir: Path) -> tuple[bytes, bytes]:
    """The master's pair."""
    return _load(Path(keys_dir) / "client.key_secret", False, _master_hint(keys_dir))


def _master_hint(keys_dir: Path) -> str:
    return (f"make the keys on the slave with `teleop keys generate {keys_dir}` and copy "
            f"{', '.join(MASTER_FILES)} into {keys_dir}/ on the master (or give --keys DIR, "
            "or --curve off on a trusted network)")
