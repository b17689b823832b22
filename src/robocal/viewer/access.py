"""Who may use a robocal page: the Host and Origin checks, malformed messages, the exposure warning.

viser serves its page and its websocket from one ``websockets`` server it starts in a thread of its own and
offers no hook into it. :func:`guarded_server` wraps ``websockets.asyncio.server.serve`` for the time the
``viser.ViserServer`` starts (under a lock, then restored) and so gives the server robocal's
:class:`PageAccess`:

* every HTTP request and websocket handshake is checked before viser sees it (``process_request``): the
  ``Host`` header must name this machine — an IP address, ``localhost``, the host the page was served on, this
  machine's name — or a host of ``--allow-origin``; an ``Origin`` header, which browsers send with every
  websocket and cross-site request, must be the page's own origin (``http://`` + the ``Host``) or one given with
  ``--allow-origin``. Anything else is answered ``403 Forbidden``. That stops another web page the operator has
  open (a foreign Origin) and DNS rebinding (a foreign name in Host) from reading the joint table or working the
  controls;
* a client whose messages the page cannot read (the connection handler raises) is disconnected with close code
  1003 and reported once per client address as one warning line, not a traceback per message.

Refusals and bad clients are logged on the ``robocal.viewer`` logger (the CLI prints them as ``warning:``
lines); :func:`exposure_warning` words the warning for a page served beyond the loopback interface.
"""

from __future__ import annotations

import http
import ipaddress
import logging
import socket
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any
from urllib.parse import urlsplit

from ..errors import UsageError

__all__ = ["LOGGER", "PageAccess", "exposure_warning", "guarded_server", "is_loopback", "parse_allowed_origins"]

LOGGER = logging.getLogger("robocal.viewer")
_MAX_REMEMBERED = 1024
"""Distinct refused values / bad client addresses remembered (each reported once); older ones are forgotten."""
_WILDCARDS = ("0.0.0.0", "::", "")
_SERVE_LOCK = threading.Lock()


def _ip(name: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(name.strip("[]").split("%", 1)[0])
    except ValueError:
        return None


def is_loopback(host: str) -> bool:
    """Whether serving on ``host`` keeps the page on this machine (``127.0.0.0/8``, ``::1``, ``localhost``)."""
    if host.lower().rstrip(".") == "localhost":
        return True
    ip = _ip(host)
    return ip is not None and ip.is_loopback


def _split_host(value: str) -> tuple[str, int | None] | None:
    """``host[:port]`` / ``[v6][:port]`` → (lower-case host without brackets or final dot, port or None)."""
    try:
        parts = urlsplit(f"//{value.strip()}")
        port = parts.port
    except ValueError:
        return None
    host = (parts.hostname or "").rstrip(".")
    return (host, port) if host else None


def _origin(value: str) -> str | None:
    """An origin ``scheme://host[:port]`` normalised (lower case, default port dropped), or None if it is not one."""
    try:
        parts = urlsplit(value.strip())
        port = parts.port
    except ValueError:
        return None
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.path not in ("", "/"):
        return None
    if parts.query or parts.fragment or parts.username or parts.password:
        return None
    host = parts.hostname.rstrip(".")
    host = f"[{host}]" if ":" in host else host
    default = 80 if parts.scheme == "http" else 443
    return f"{parts.scheme}://{host}" + ("" if port in (None, default) else f":{port}")


def parse_allowed_origins(values: Sequence[str]) -> tuple[str, ...]:
    """Check and normalise ``--allow-origin`` values: origins ``http(s)://host[:port]``, or ``*`` for any.

    Raises:
        UsageError: A value that is not an origin (naming it).
    """
    out: list[str] = []
    for value in values:
        if value.strip() == "*":
            out.append("*")
            continue
        norm = _origin(value)
        if norm is None:
            raise UsageError(
                f"--allow-origin {value!r}: expected an origin such as http://robot-pc.local:8080 (scheme, host, "
                "optional port; no path), or * for any"
            )
        out.append(norm)
    return tuple(dict.fromkeys(out))


class PageAccess:
    """The Host / Origin rules of one served page, and its once-per-value reports.

    Args:
        host: The interface the page is served on (``--host``).
        allowed_origins: Normalised ``--allow-origin`` values (:func:`parse_allowed_origins`); ``*`` allows any.
        log: Where a refusal or a bad client is reported (one line each, once per value).
    """

    def __init__(
        self, host: str, allowed_origins: Sequence[str] = (), log: Callable[[str], None] | None = None
    ) -> None:
        self.any_origin = "*" in allowed_origins
        self.origins = frozenset(o for o in allowed_origins if o != "*")
        names = {"localhost", host.lower().strip("[]").rstrip(".")}
        if host in _WILDCARDS:
            names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
        for origin in self.origins:
            split = _split_host(origin.split("://", 1)[1])
            if split is not None:
                names.add(split[0])
        self.names = frozenset(n for n in names if n)
        self._log = log or LOGGER.warning
        self._reported: dict[str, None] = {}
        self._lock = threading.Lock()

    def host_allowed(self, host_header: str | None) -> bool:
        """Whether a ``Host`` header names this machine (IP address, ``localhost``, served host, its name)."""
        if self.any_origin:
            return True
        split = _split_host(host_header or "")
        if split is None:
            return False
        name = split[0]
        return _ip(name) is not None or name in self.names or name.endswith(".localhost")

    def origin_allowed(self, origin: str | None, host_header: str | None) -> bool:
        """Whether an ``Origin`` header (None: not sent, e.g. a script) is the page's own or an allowed one."""
        if origin is None or self.any_origin:
            return True
        norm = _origin(origin)
        if norm is None:
            return False  # "null" (a file, a sandboxed frame) or garbage
        if norm in self.origins:
            return True
        own = _origin(f"http://{host_header}") if host_header else None
        return own is not None and norm == own

    def refusal(self, host_header: str | None, origin: str | None) -> str | None:
        """Why a request is refused (a sentence naming the header), or None when it is allowed."""
        if not self.host_allowed(host_header):
            return f"Host {host_header!r} is not this machine's"
        if not self.origin_allowed(origin, host_header):
            return f"Origin {origin!r} is not the page's own"
        return None

    def report_once(self, key: str, line: str) -> None:
        """Log ``line`` the first time ``key`` is seen (a bounded memory of keys)."""
        with self._lock:
            if key in self._reported:
                return
            self._reported[key] = None
            if len(self._reported) > _MAX_REMEMBERED:
                self._reported.pop(next(iter(self._reported)))
        self._log(line)

    def process_request(self, inner: Callable[[Any, Any], Any] | None) -> Callable[[Any, Any], Any]:
        """A ``websockets`` ``process_request`` that answers refused requests 403, else defers to ``inner``."""

        def check(connection: Any, request: Any) -> Any:
            why = self.refusal(request.headers.get("Host"), request.headers.get("Origin"))
            if why is not None:
                self.report_once(
                    f"refused:{why}",
                    f"page: refused a request from {_address(connection)}: {why} (--allow-origin allows others)",
                )
                return connection.respond(http.HTTPStatus.FORBIDDEN, f"refused: {why}\n")
            return inner(connection, request) if inner is not None else None

        return check

    def handler(self, inner: Callable[[Any], Any]) -> Callable[[Any], Any]:
        """Wrap viser's connection handler: a client whose messages fail is closed (1003) and reported once."""

        async def guarded(connection: Any) -> None:
            try:
                await inner(connection)
            except Exception as exc:
                who = _address(connection).rsplit(":", 1)[0]
                self.report_once(
                    f"client:{who}",
                    f"page: closed the connection of {who}: it sent a message the page cannot read "
                    f"({type(exc).__name__}: {str(exc)[:200]}); further ones from it are not reported",
                )
                await connection.close(1003, "unreadable message")

        return guarded


def _address(connection: Any) -> str:
    addr = getattr(connection, "remote_address", None)
    if isinstance(addr, tuple) and len(addr) >= 2:
        return f"[{addr[0]}]:{addr[1]}" if ":" in str(addr[0]) else f"{addr[0]}:{addr[1]}"
    return "an unknown address"


@contextmanager
def guarded_server(access: PageAccess) -> Iterator[None]:
    """While the ``with`` body starts a ``viser.ViserServer``, its websocket server gets ``access``'s checks.

    ``websockets.asyncio.server.serve`` is replaced for that time only (viser calls it from its own thread while
    the constructor waits), under a lock so that two pages starting at once each get their own rules.
    """
    import websockets.asyncio.server as ws_server

    with _SERVE_LOCK:
        original = ws_server.serve

        def serve(handler: Any, *args: Any, **kwargs: Any) -> Any:
            kwargs["process_request"] = access.process_request(kwargs.get("process_request"))
            return original(access.handler(handler), *args, **kwargs)

        ws_server.serve = serve  # type: ignore[assignment,misc]
        try:
            yield
        finally:
            ws_server.serve = original  # type: ignore[misc]


def outward_address() -> str:
    """This machine's address as other machines reach it (the interface of the default route), else its name.

    Nothing is sent: connecting a UDP socket only picks the interface.
    """
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(("192.0.2.1", 9))  # TEST-NET-1: never routed anywhere real
        return str(probe.getsockname()[0])
    except OSError:
        return socket.gethostname()
    finally:
        probe.close()


def exposure_warning(host: str, url: str) -> str | None:
    """The warning for a page served on ``host`` beyond this machine (None on loopback)."""
    if is_loopback(host):
        return None
    where = "every network interface of this machine" if host in _WILDCARDS else f"the interface {host}"
    return (
        f"the page is served on {where} ({url}): anyone who can reach this machine on that port can watch the "
        "robot and use the page's controls (serve on 127.0.0.1 and tunnel, e.g. ssh -L, to keep it private)"
    )
