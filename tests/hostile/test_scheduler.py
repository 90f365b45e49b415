"""``--scheduler`` fails in bounded time with one line for anything not a Dask scheduler
(issue 19): an HTTP server, a silent listener, unsupported schemes, malformed addresses."""

from __future__ import annotations

import http.server
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.studies import execute

STUDY = {
    "name": "sched",
    "seed": 1,
    "dt": 0.05,
    "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
    "generators": [{"type": "near_singular", "count": 1, "duration": [1.0, 1.5]}],
    "controllers": [{"name": "pinv", "backend": {"type": "pinv"}}],
}


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib name
        pass


@pytest.fixture
def http_server() -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _QuietHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def silent_listener() -> Iterator[str]:
    """Accepts connections and never sends a byte."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    accepted: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        listener.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(listener.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(2)
        for conn in accepted:
            conn.close()
        listener.close()


def _study(tmp_path: Path, address: str) -> tuple[int, str, float]:
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(STUDY))
    out = tmp_path / "out"
    tic = time.monotonic()
    status = main(["study", str(path), "--out", str(out), "--scheduler", address, "--quiet"])
    return status, str(out), time.monotonic() - tic


def _check(capsys: pytest.CaptureFixture[str], status: int, out: str, needle: str) -> None:
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err, err
    assert err.count("\n") == 1 and needle in err, err
    assert not Path(out).exists(), "the folder was touched before the scheduler was checked"


def test_http_server_is_not_a_scheduler(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    http_server: str,
) -> None:
    assert execute.CONNECT_TIMEOUT + 5 <= 20  # the shipped bound, with start-up slack
    monkeypatch.setattr(execute, "CONNECT_TIMEOUT", 2.0)  # the bound scales with it
    status, out, elapsed = _study(tmp_path, http_server)
    _check(capsys, status, out, "cannot reach a Dask scheduler at")
    assert elapsed <= 2.0 + 5


def test_silent_listener_fails_in_bounded_time(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    silent_listener: str,
) -> None:
    monkeypatch.setattr(execute, "CONNECT_TIMEOUT", 2.0)  # shipped: 10 s; the bound is the same
    status, out, elapsed = _study(tmp_path, silent_listener)
    _check(capsys, status, out, "no answer within 2 s")
    assert elapsed <= 2.0 + 5


@pytest.mark.parametrize(
    ("address", "needle"),
    [
        ("ucx://127.0.0.1:8786", "scheme ucx:// is not supported"),
        ("inproc://x:1", "scheme inproc:// is not supported"),
        ("tcp://127.0.0.1:99999", "port must be in 1..65535"),
        ("not an address", "expected tcp://HOST:PORT"),
    ],
)
def test_unusable_addresses_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], address: str, needle: str
) -> None:
    status, out, _ = _study(tmp_path, address)
    _check(capsys, status, out, needle)
