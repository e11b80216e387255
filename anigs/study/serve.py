"""``anigs study serve``: serve a built study folder on 127.0.0.1 and collect the posted answers.

``GET`` serves the page, its script and style and ``videos/*.mp4`` (single byte ranges too, so
videos seek), nothing else: not the answers file. ``POST /answers``
takes one answer or ``{"answers": [...]}`` (JSON, at most ``MAX_BODY`` bytes, ``MAX_BATCH``
answers), checks every answer against the schema and the study's manifest, and appends the batch
to a JSONL file in one locked ``write`` + ``fsync`` (a batch is stored whole or not at all).
A malformed post gets ``400`` with a JSON body ``{"error": "..."}`` naming the problem; an answer
already stored verbatim is not stored twice (re-sent answers after a lost reply are harmless).
Bounded: requests of at most ``MAX_BODY`` bytes, ``MAX_CONNECTIONS`` at a time, 30 s to send
one, ``MAX_ANSWERS`` per file; :class:`StudyServer` binds 127.0.0.1 (by default) and stops on ``stop()``.
"""
from __future__ import annotations

import fcntl
import json
import logging
import os
import threading
from datetime import datetime, timezone
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from anigs.io import read_json
from anigs.study.layout import Outputs
from anigs.study.schema import answer_key, answer_problems

log = logging.getLogger("anigs.study")

MAX_BODY = 256 * 1024
MAX_BATCH = 500
MAX_CONNECTIONS = 32  # requests handled at once; more get 503 at once (videos are small, posts are tiny)
MAX_ANSWERS = 1_000_000  # per answers file: beyond this the server refuses (507) instead of growing forever


class AnswerStore:
    """The JSONL answers file: validation against the manifest, dedup, locked atomic appends."""

    def __init__(self, path: str | Path, manifest: dict[str, Any]):
        self.path = Path(path)
        self.manifest = manifest
        self.pairs = {t["id"]: t for t in manifest["trials"]}
        self.lock = threading.Lock()
        self.seen: dict[tuple[str, str, str, str], str] = {}
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                try:
                    a = json.loads(line)
                    self.seen[answer_key(a)] = _canonical(a)
                except (ValueError, KeyError, TypeError):
                    continue  # a damaged line stays in the file; the tally reports it

    def problems(self, a: Any) -> list[str]:
        """Schema problems, then mismatches with this study's manifest."""
        p = answer_problems(a)
        if p:
            return p
        if a["study_id"] != self.manifest["study_id"]:
            return [f"study_id {a['study_id']!r} is not this study's ({self.manifest['study_id']!r})"]
        t = self.pairs.get(a["pair"])
        if t is None:
            return [f"pair {a['pair']!r} is not in this study"]
        diff = [k for k in ("scene", "view", "ours", "other") if a[k] != t[k]]
        if diff:
            return [f"fields {diff} do not match pair {a['pair']!r} of the manifest"]
        if a["n_trials"] != len(self.pairs):
            return [f"n_trials {a['n_trials']} is not this study's {len(self.pairs)}"]
        return []

    def append(self, answers: list[dict[str, Any]]) -> tuple[int, int]:
        """Store the new answers in one write; return (stored, duplicates)."""
        now = datetime.now(timezone.utc).isoformat(timespec="milliseconds")
        with self.lock:
            new, dup = [], 0
            for a in answers:
                key, canon = answer_key(a), _canonical(a)
                if self.seen.get(key) == canon:
                    dup += 1
                    continue
                new.append((key, canon, json.dumps({**a, "received_at": now}, sort_keys=True)))
            if len(self.seen) + len(new) > MAX_ANSWERS:
                raise OverflowError(f"answers file holds {len(self.seen)} answers; limit {MAX_ANSWERS}")
            if new:
                data = "".join(line + "\n" for _, _, line in new).encode()
                self.path.parent.mkdir(parents=True, exist_ok=True)
                fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX)  # other processes appending to the same file wait
                    view = memoryview(data)
                    while view:
                        view = view[os.write(fd, view):]
                    os.fsync(fd)
                finally:
                    os.close(fd)
                for key, canon, _ in new:
                    self.seen[key] = canon
            return len(new), dup


def _canonical(a: dict[str, Any]) -> str:
    return json.dumps({k: v for k, v in a.items() if k != "received_at"}, sort_keys=True)


def parse_post(body: bytes) -> list[Any]:
    """The answers of a POST body; raise ValueError with a clear message when it is not one."""
    try:
        data = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"body is not valid UTF-8 JSON: {exc}") from None
    if isinstance(data, dict) and set(data) == {"answers"}:
        data = data["answers"]
        if not isinstance(data, list) or not data:
            raise ValueError("'answers' must be a non-empty list")
        if len(data) > MAX_BATCH:
            raise ValueError(f"at most {MAX_BATCH} answers per post, got {len(data)}")
        return data
    if isinstance(data, dict):
        return [data]
    raise ValueError(f"expected an answer object or {{\"answers\": [...]}}, got {type(data).__name__}")


def _public(url_path: str) -> bool:
    """Only the page, its script and style, and the videos are served."""
    p = url_path.split("?")[0].split("#")[0]
    if p in Outputs.public():
        return True
    parts = p.split("/")
    return len(parts) == 3 and parts[1] == "videos" and parts[2].endswith(".mp4") and ".." not in parts[2]


class StudyHandler(SimpleHTTPRequestHandler):
    """Static files of the study folder + ``POST /answers``."""

    store: AnswerStore
    timeout = 30  # seconds a client may take to send a request

    def log_message(self, fmt: str, *args: Any) -> None:
        log.debug("%s " + fmt, self.address_string(), *args)

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-store")
        self.send_header("Access-Control-Allow-Origin", "*")  # a page opened from file:// may post here
        super().end_headers()

    def _json(self, status: int, obj: dict[str, Any]) -> None:
        body = json.dumps(obj).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_OPTIONS(self) -> None:  # noqa: N802 - CORS preflight
        self.send_response(HTTPStatus.NO_CONTENT)
        self.send_header("Access-Control-Allow-Methods", "GET, POST, OPTIONS")
        self.send_header("Access-Control-Allow-Headers", "Content-Type")
        self.end_headers()

    def do_POST(self) -> None:  # noqa: N802
        if self.path.split("?")[0].rstrip("/") != "/answers":
            return self._json(404, {"error": f"POST goes to /answers, not {self.path}"})
        ctype = self.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if ctype != "application/json":
            return self._json(400, {"error": f"Content-Type must be application/json, got {ctype or 'none'!r}"})
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            return self._json(411, {"error": "Content-Length header required"})
        if length < 0 or length > MAX_BODY:
            self.close_connection = True
            return self._json(413, {"error": f"body of {length} bytes exceeds the limit of {MAX_BODY}"})
        try:
            answers = parse_post(self.rfile.read(length))
        except ValueError as exc:
            return self._json(400, {"error": str(exc)})
        errors = [f"answer {i}: " + "; ".join(p) for i, a in enumerate(answers) if (p := self.store.problems(a))]
        if errors:
            return self._json(400, {"error": "malformed answers, none stored: " + " | ".join(errors[:10])})
        try:
            stored, dup = self.store.append(answers)
        except OverflowError as exc:
            return self._json(507, {"error": str(exc)})
        self._json(200, {"stored": stored, "duplicates": dup})

    def send_head(self):  # noqa: ANN201 - single byte ranges, so the browser can seek in videos
        self._range_left: int | None = None
        if not _public(self.path):  # e.g. the answers: participants must not read each other's answers
            self.send_error(404, "not part of the study page")
            return None
        rng = self.headers.get("Range", "")
        path = self.translate_path(self.path)
        if not rng.startswith("bytes=") or not os.path.isfile(path):
            return super().send_head()
        size = os.path.getsize(path)
        try:
            a, b = rng[6:].split(",")[0].split("-")
            start, end = (int(a), int(b) if b else size - 1) if a else (max(0, size - int(b)), size - 1)
        except ValueError:
            return super().send_head()
        if start >= size or start > end:
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{size}")
            self.end_headers()
            return None
        end = min(end, size - 1)
        f = open(path, "rb")
        f.seek(start)
        self.send_response(206)
        self.send_header("Content-Type", self.guess_type(path))
        self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
        self.send_header("Content-Length", str(end - start + 1))
        self.send_header("Accept-Ranges", "bytes")
        self.end_headers()
        self._range_left = end - start + 1
        return f

    def copyfile(self, source, outputfile) -> None:  # noqa: ANN001
        left = getattr(self, "_range_left", None)
        if left is None:
            return super().copyfile(source, outputfile)
        while left > 0:
            chunk = source.read(min(64 * 1024, left))
            if not chunk:
                break
            outputfile.write(chunk)
            left -= len(chunk)


class _BoundedServer(ThreadingHTTPServer):
    """A threading server that handles at most ``MAX_CONNECTIONS`` requests at a time."""

    daemon_threads = True

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.slots = threading.BoundedSemaphore(MAX_CONNECTIONS)

    def process_request(self, request, client_address) -> None:  # noqa: ANN001
        if not self.slots.acquire(blocking=False):
            try:
                request.sendall(b"HTTP/1.0 503 Service Unavailable\r\nContent-Length: 0\r\nRetry-After: 1\r\n\r\n")
            finally:
                self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request, client_address) -> None:  # noqa: ANN001
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()


class StudyServer:
    """The study server on 127.0.0.1 (port 0: a free one), run in a background thread.

    ``with StudyServer(folder) as s: ... s.url ...``, or ``start()`` / ``stop()``.
    """

    def __init__(self, folder: str | Path, answers: str | Path | None = None, port: int = 0, host: str = "127.0.0.1"):
        layout = Outputs(folder)
        self.folder = layout.root
        manifest = read_json(layout.path("manifest"))
        self.store = AnswerStore(answers or layout.path("answers"), manifest)
        handler = type("BoundStudyHandler", (StudyHandler,), {"store": self.store})
        self.httpd = _BoundedServer((host, port), partial(handler, directory=str(self.folder)))
        self.thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> "StudyServer":
        self.thread = threading.Thread(target=self.httpd.serve_forever, name="anigs-study-server", daemon=True)
        self.thread.start()
        return self

    def stop(self) -> None:
        if self.thread is not None:
            self.httpd.shutdown()
            self.thread.join(timeout=10)
            self.thread = None
        self.httpd.server_close()

    def __enter__(self) -> "StudyServer":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()
