"""Who may talk to the collision server: local by default, CURVE beyond this machine.

A drill rig's controller, simulator and scanner are separate processes, often on separate
computers (P-IV, P-V §II): the collision server may have to listen on a network. A
server that accepts robot models and moves the safety distances of a machine must not be
open to whoever reaches the port, so:

- by default it binds ``ipc://`` (a Unix socket) or a loopback address (``127.0.0.0/8``,
  ``[::1]``, ``localhost``);
- binding anything else (an interface, ``*``, ``0.0.0.0``, a host name, another
  transport) requires CURVE authentication and encryption (ZeroMQ's CurveZMQ with the
  ZAP handler of :mod:`zmq.auth`): the server proves itself with its secret key and
  accepts only clients whose public keys lie in its ``authorized/`` folder;
- unless the user passes ``--insecure`` explicitly, which binds without either.

Keys are made by ``reachwise serve keygen DIR`` (:func:`keygen`)::

    DIR/server.key           server public key      (give to clients)
    DIR/server.key_secret    server secret key      (server only, mode 0600)
    DIR/client.key           a client public key
    DIR/client.key_secret    that client's secret   (client only, mode 0600)
    DIR/authorized/          public keys the server accepts (client.key to start with)

A secret key file that group or others can read is refused, as ssh refuses one.
No host name is ever resolved to decide what "local" means: only literal loopback
addresses and ``localhost`` are local.
"""

from __future__ import annotations

import ipaddress
import os
import shutil
import stat
from dataclasses import dataclass
from pathlib import Path

import zmq
import zmq.auth

from reachwise.errors import InputError

#: Default address: loopback TCP (an ``ipc://`` path is local too).
DEFAULT_BIND = "tcp://127.0.0.1:5590"
SERVER = "server"
CLIENT = "client"
AUTHORIZED = "authorized"


class SecurityError(InputError):
    """A bind or key setup that the security policy refuses."""


@dataclass(frozen=True)
class ServerKeys:
    """The server's key pair (z85 bytes) and the folder of authorized client keys."""

    public: bytes
    secret: bytes
    authorized: Path


@dataclass(frozen=True)
class ClientKeys:
    """A client's key pair and the server's public key (z85 bytes)."""

    public: bytes
    secret: bytes
    server: bytes


@dataclass(frozen=True)
class BindPlan:
    """What :func:`plan_bind` decided: the address, whether it is local, and the keys
    (None: no CURVE)."""

    address: str
    local: bool
    keys: ServerKeys | None

    @property
    def curve(self) -> bool:
        return self.keys is not None


def is_local(address: str) -> bool:
    """True for ``ipc://`` and ``inproc://`` endpoints and TCP on a literal loopback
    address or ``localhost`` (no name resolution)."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        return False
    if scheme in ("ipc", "inproc"):
        return bool(rest)
    if scheme != "tcp":
        return False
    host, _, port = rest.rpartition(":")
    if not port or ";" in rest:  # "tcp://src;dst" source-address syntax: not ours
        return False
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # "*", an interface name or a host name


def plan_bind(address: str, keys_dir: str | os.PathLike[str] | None, insecure: bool) -> BindPlan:
    """Apply the policy: keys given → CURVE on any address; a non-local address needs
    keys or an explicit ``insecure``. Raises :class:`SecurityError` otherwise."""
    if not isinstance(address, str) or "://" not in address:
        raise SecurityError("bind", address, "expected an endpoint such as tcp://127.0.0.1:5590")
    local = is_local(address)
    keys = load_server_keys(keys_dir) if keys_dir is not None else None
    if not local and keys is None and not insecure:
        raise SecurityError(
            "bind",
            address,
            "not a loopback or ipc:// address: the collision server would be reachable from "
            "other machines. Give CURVE keys (--keys DIR, made by `reachwise serve keygen "
            "DIR`) or pass --insecure explicitly",
        )
    return BindPlan(address, local, keys)


def keygen(directory: str | os.PathLike[str], force: bool = False) -> dict[str, Path]:
    """Create the server and client key pairs and the ``authorized/`` folder (see the
    module docstring). Refuses to overwrite existing keys unless ``force``."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    existing = [p for p in (d / f"{SERVER}.key_secret", d / f"{CLIENT}.key_secret") if p.exists()]
    if existing and not force:
        raise SecurityError(str(existing[0]), "", "keys exist already; pass force to replace them")
    out: dict[str, Path] = {}
    old_umask = os.umask(0o077)  # secret files are never readable by others, not even briefly
    try:
        for who in (SERVER, CLIENT):
            public, secret = zmq.auth.create_certificates(str(d), who)
            os.chmod(public, 0o644)
            os.chmod(secret, 0o600)
            out[who] = Path(public)
            out[f"{who}_secret"] = Path(secret)
    finally:
        os.umask(old_umask)
    auth = d / AUTHORIZED
    auth.mkdir(exist_ok=True)
    shutil.copyfile(out[CLIENT], auth / f"{CLIENT}.key")
    out[AUTHORIZED] = auth
    return out


def _load_secret(path: Path) -> tuple[bytes, bytes]:
    if not path.is_file():
        raise SecurityError(
            str(path), "", "no such key file (make keys with `reachwise serve keygen DIR`)"
        )
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        raise SecurityError(
            str(path),
            "",
            f"secret key is readable by group or others (mode {mode:o}); chmod 600 it",
        )
    try:
        public, secret = zmq.auth.load_certificate(str(path))
    except (OSError, ValueError) as exc:
        raise SecurityError(str(path), "", f"not a key file: {exc}") from None
    if not secret:
        raise SecurityError(str(path), "", "holds no secret key")
    return public, secret


def _load_public(path: Path) -> bytes:
    if not path.is_file():
        raise SecurityError(str(path), "", "no such key file")
    try:
        public, _ = zmq.auth.load_certificate(str(path))
    except (OSError, ValueError) as exc:
        raise SecurityError(str(path), "", f"not a key file: {exc}") from None
    return public


def load_server_keys(directory: str | os.PathLike[str]) -> ServerKeys:
    """The server's key pair and authorized-keys folder from a keygen directory."""
    d = Path(directory)
    public, secret = _load_secret(d / f"{SERVER}.key_secret")
    auth = d / AUTHORIZED
    if not auth.is_dir() or not any(auth.glob("*.key")):
        raise SecurityError(str(auth), "", "no authorized client keys (*.key) in this folder")
    return ServerKeys(public, secret, auth)


def load_client_keys(directory: str | os.PathLike[str], name: str = CLIENT) -> ClientKeys:
    """A client's key pair (``NAME.key_secret``) and the server's public key."""
    d = Path(directory)
    public, secret = _load_secret(d / f"{name}.key_secret")
    return ClientKeys(public, secret, _load_public(d / f"{SERVER}.key"))


def secure_server_socket(sock: zmq.Socket[bytes], keys: ServerKeys) -> None:
    """Make ``sock`` a CURVE server (call before bind; a ZAP authenticator must run)."""
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_server = True


def secure_client_socket(sock: zmq.Socket[bytes], keys: ClientKeys) -> None:
    """Make ``sock`` a CURVE client of the server whose public key is ``keys.server``."""
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_serverkey = keys.server


__all__ = [
    "DEFAULT_BIND",
    "BindPlan",
    "ClientKeys",
    "SecurityError",
    "ServerKeys",
    "is_local",
    "keygen",
    "load_client_keys",
    "load_server_keys",
    "plan_bind",
    "secure_client_socket",
    "secure_server_socket",
]
