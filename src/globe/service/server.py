"""Running the service with uvicorn: the listening socket is bound first (a port in use or a
host that does not resolve is a one-line :class:`ConfigError` before anything is printed), and
uvicorn's HTTP protocol (httptools) gets limits on what it reads before the app sees a request:
the size of the request line and headers (431 above ``service.max_header_bytes``) and the time
they may take (``service.header_timeout_s``; a silent or half-sent request is closed).

The process also tunes glibc's allocator (:func:`tune_allocator`). A household upload is
megabytes of request body, freed once the household is built, and glibc's default mmap threshold
rises after the first such block is freed, so later bodies land in the heap between the models
of the households built meanwhile and stay in the process as freed, unusable memory: the
threshold is fixed instead. And the request threads share one malloc arena: Python threads run
one at a time (the GIL), so an arena per thread buys no parallelism, only freed memory kept
apart in each."""

from __future__ import annotations

import asyncio
import ctypes
import socket
from typing import Any

from globe.config import ServiceConfig
from globe.errors import ConfigError, MissingExtraError


def bind(host: str, port: int) -> socket.socket:
    """A socket bound to ``host:port`` (uvicorn listens on it)."""
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                                             flags=socket.AI_PASSIVE)[0]
    except (socket.gaierror, UnicodeError) as err:
        raise ConfigError(f"--host {host!r}: cannot resolve it ({getattr(err, 'strerror', None) or err})") from None
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
    except OSError as err:
        sock.close()
        hint = "; choose another --port, or stop what uses it" if err.errno == 98 else ""
        raise ConfigError(f"cannot listen on {host}:{port}: {err.strerror or err}{hint}") from None
    return sock


def guarded_protocol(service: ServiceConfig) -> type[asyncio.Protocol]:
    """uvicorn's httptools protocol with the header size and time limits of ``service``."""
    try:
        from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
    except ImportError as err:
        raise MissingExtraError("httptools", "service") from err

    max_bytes, timeout_s = service.max_header_bytes, service.header_timeout_s

    class GuardedHttpToolsProtocol(HttpToolsProtocol):
        """Counts the bytes that arrive while a request's headers are incomplete, and times them."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._awaiting_headers = True
            self._header_bytes = 0
            self._header_timer: asyncio.TimerHandle | None = None

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm()

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self._awaiting_headers and not self.transport.is_closing():
                # headers still incomplete after this piece: it is (almost all) header bytes
                self._header_bytes += len(data)
                if self._header_bytes > max_bytes:
                    self._refuse(431, f"request headers over {max_bytes} bytes (service.max_header_bytes)")

        def on_message_begin(self) -> None:
            super().on_message_begin()
            self._awaiting_headers, self._header_bytes = True, 0
            if self._header_timer is None:
                self._arm()

        def on_headers_complete(self) -> None:
            self._awaiting_headers = False
            self._disarm()
            super().on_headers_complete()

        def _arm(self) -> None:
            self._disarm()
            self._header_timer = self.loop.call_later(timeout_s, self._too_slow)

        def _disarm(self) -> None:
            if self._header_timer is not None:
                self._header_timer.cancel()
                self._header_timer = None

        def _too_slow(self) -> None:
            self._header_timer = None
            if self._awaiting_headers and not self.transport.is_closing():
                self._refuse(408, f"request headers did not arrive within {timeout_s:g} s (service.header_timeout_s)")

        def _refuse(self, status: int, detail: str) -> None:
            self._disarm()
            body = ('{"detail": "%s", "field": "headers"}' % detail).encode()
            reason = {408: b"Request Timeout", 431: b"Request Header Fields Too Large"}[status]
            self.transport.write(b"HTTP/1.1 %d %s\r\ncontent-type: application/json\r\ncontent-length: %d\r\n"
                                 b"connection: close\r\n\r\n%s" % (status, reason, len(body), body))
            self.transport.close()

    return GuardedHttpToolsProtocol


M_MMAP_THRESHOLD, M_ARENA_MAX = -3, -8  # glibc's mallopt parameters (malloc.h)
MMAP_THRESHOLD_BYTES = 1 << 20
"""Blocks from 1 MiB up (request bodies, not the ~100 KB day texts) are mapped on their own and
returned to the system when freed (benchmarks/bench_service.py: memory per household)."""


def tune_allocator(threshold: int = MMAP_THRESHOLD_BYTES, arenas: int = 1) -> bool:
    """Fix glibc's mmap threshold at ``threshold`` bytes and its arenas at ``arenas`` (see the
    module doc); False where the C library has no ``mallopt`` (musl, macOS) or refuses, which
    changes nothing else."""
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's own symbols: its C library's, whatever its name
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, threshold)) and bool(mallopt(M_ARENA_MAX, arenas))


def run(app: Any, service: ServiceConfig, sock: socket.socket) -> None:
    """Serve ``app`` on the bound ``sock`` until interrupted."""
    try:
        import uvicorn
    except ImportError as err:
        raise MissingExtraError("uvicorn", "service") from err
    tune_allocator()
    config = uvicorn.Config(app, http=guarded_protocol(service), log_level="warning")
    uvicorn.Server(config).run(sockets=[sock])
