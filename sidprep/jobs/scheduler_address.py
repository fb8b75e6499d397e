"""The address of a Dask scheduler (``--scheduler``, ``[batch] scheduler``): its form checked, and
the peer probed before dask.distributed connects to it.

Why the probe: distributed's TCP comm (``distributed/comm/tcp.py``, ``TCP.read``) takes the first
8 bytes a peer sends as the length of a message and allocates a buffer of that size before reading
it; any other service on the port (a web server, ssh) makes it allocate whatever its first bytes
spell.  A Dask scheduler speaks first: on every new connection it writes its handshake
(``distributed/comm/core.py``, ``Listener.on_connection``: ``comm.write(local_info)``), framed as

    total (uint64 LE) | n_frames (uint64 LE) | n_frames lengths (uint64 LE) | frames (msgpack),

with total = the bytes after it (a few dozen: the keys "compression", "python",
"pickle-protocol").  :func:`probe_scheduler` reads at most HANDSHAKE_BYTES of it within
PROBE_TIMEOUT_S and checks that layout; only then is the address handed to distributed.
"""

from __future__ import annotations

import socket
import struct
from urllib.parse import urlsplit

from sidprep.errors import InputError, printable

#: the schemes sidprep connects with (plain TCP, as ``dask scheduler`` listens by default)
SCHEMES = ("tcp",)
#: most bytes of a scheduler's handshake read by the probe (it sends ~60)
HANDSHAKE_BYTES = 4096
#: most frames of a handshake (one msgpack frame)
HANDSHAKE_FRAMES = 8
#: seconds the probe waits to connect and for the handshake
PROBE_TIMEOUT_S = 5.0
#: a msgpack key of every scheduler's handshake (distributed.comm.core.Comm.handshake_info)
HANDSHAKE_KEY = b"pickle-protocol"


def scheduler_address(text: str, where: str = "--scheduler") -> tuple[str, int]:
    """(host, port) of a scheduler address ``tcp://HOST:PORT`` (or ``HOST:PORT``); InputError starting
    with ``where`` (the option or the file's key) for any other form."""
    text = str(text).strip()
    fix = "give the scheduler's address as tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786)"
    shown = printable(text)
    parts = urlsplit(text if "://" in text else f"tcp://{text}")
    if parts.scheme not in SCHEMES:
        raise InputError(f"{where} {shown}: unknown scheme {parts.scheme!r} (sidprep connects by tcp); {fix}")
    try:
        port = parts.port
    except ValueError:
        port = None
    host = parts.hostname
    if not host or port is None or not 1 <= port <= 65535 or parts.path not in ("", "/") or parts.query \
            or parts.fragment or parts.username or parts.password:
        raise InputError(f"{where} {shown}: not a scheduler address; {fix}")
    return host, port


def probe_scheduler(text: str, where: str = "--scheduler", timeout: float = PROBE_TIMEOUT_S) -> str:
    """The address ``tcp://HOST:PORT`` once the peer there has sent a Dask scheduler's handshake
    (module docstring), read with at most HANDSHAKE_BYTES and ``timeout`` s; InputError when it
    cannot be reached or speaks another protocol."""
    host, port = scheduler_address(text, where)
    address = f"tcp://{host}:{port}" if ":" not in host else f"tcp://[{host}]:{port}"
    try:
        with socket.create_connection((host, port), timeout=timeout) as conn:
            head = _read(conn, 8)
            total = struct.unpack("<Q", head)[0] if len(head) == 8 else 0
            body = _read(conn, total) if 16 <= total <= HANDSHAKE_BYTES else b""
    except OSError as exc:
        raise InputError(f"{where} {address}: cannot reach the scheduler ({exc.strerror or exc}); start it "
                         "(dask scheduler) or check the host and port") from None
    if not is_handshake(body, total):
        raise InputError(f"{where} {address}: the peer there is not a Dask scheduler (its first bytes are not a "
                         "scheduler's handshake); give the address the scheduler prints (Scheduler at: tcp://...)")
    return address


def is_handshake(body: bytes, total: int) -> bool:
    """Whether ``body`` (``total`` bytes announced) is a framed Dask handshake: n_frames, their
    lengths adding up to the rest, and the handshake's msgpack key in the frames."""
    if len(body) != total or total < 16:
        return False
    n = struct.unpack_from("<Q", body)[0]
    if not 1 <= n <= HANDSHAKE_FRAMES or total < 8 * (1 + n):
        return False
    lengths = struct.unpack_from(f"<{n}Q", body, 8)
    return sum(lengths) == total - 8 * (1 + n) and HANDSHAKE_KEY in body[8 * (1 + n):]


def _read(conn: socket.socket, n: int) -> bytes:
    """Up to ``n`` bytes (fewer when the peer closes), within the socket's timeout."""
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        if not chunk:
            break
        data += chunk
    return data
