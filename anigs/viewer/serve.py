"""Serve a viewer folder (the view stage's ``Outputs``: its ``index`` is the page) on the loopback
interface (``anigs view --serve``).

Only 127.0.0.1 (or "localhost") is accepted: the viewer is meant for the local machine, never
the network. :func:`start_server` runs in a background thread and is stopped with ``stop()``
(or as a context manager); :func:`serve_folder` blocks until Ctrl-C or ``duration`` seconds.
"""
from __future__ import annotations

import functools
import http.server
import logging
import threading
import time
from typing import Any, ClassVar

from anigs.io import StageFolder

log = logging.getLogger("anigs.viewer")

LOOPBACK = ("127.0.0.1", "localhost")


class _Handler(http.server.SimpleHTTPRequestHandler):
    extensions_map: ClassVar[dict[str, str]] = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                      ".js": "text/javascript", ".anigs": "application/octet-stream", ".css": "text/css"}

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")  # a rebuilt viewer shows the new scene
        super().end_headers()

    def log_message(self, fmt: str, *args: Any) -> None:
        log.debug("serve: " + fmt, *args)


class _Server(http.server.ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True


class ViewerServer:
    """A running server: ``url``, ``port``, ``stop()``."""

    def __init__(self, folder: StageFolder, port: int = 0, host: str = "127.0.0.1") -> None:
        if host not in LOOPBACK:
            raise ValueError(f"the viewer is served on the loopback interface only, not {host!r}")
        page = folder.path("index")
        if not page.is_file():
            raise FileNotFoundError(f"no viewer page ({page.name}) in {folder.root}: build the viewer first")
        handler = functools.partial(_Handler, directory=str(folder.root))
        self._httpd = _Server(("127.0.0.1", int(port)), handler)
        self.port = int(self._httpd.server_address[1])
        self.url = f"http://127.0.0.1:{self.port}/{page.relative_to(folder.root).as_posix()}"
        self._thread = threading.Thread(target=self._httpd.serve_forever, kwargs={"poll_interval": 0.2},
                                        name="anigs-viewer-server", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop serving and close the socket (idempotent)."""
        if self._thread.is_alive():
            self._httpd.shutdown()
            self._thread.join(timeout=5)
        self._httpd.server_close()

    def __enter__(self) -> ViewerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_server(folder: StageFolder, port: int = 0, host: str = "127.0.0.1") -> ViewerServer:
    """Serve ``folder`` in a background thread (port 0: any free port)."""
    return ViewerServer(folder, port, host)


def serve_folder(folder: StageFolder, port: int = 8000, host: str = "127.0.0.1",
                 duration: float | None = None) -> None:
    """Serve until Ctrl-C, or for ``duration`` seconds when given."""
    server = start_server(folder, port, host)
    print(f"anigs viewer: {server.url}  (Ctrl-C stops)", flush=True)
    try:
        end = None if duration is None else time.monotonic() + float(duration)
        while end is None or time.monotonic() < end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
