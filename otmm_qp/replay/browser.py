"""Headless Chromium over the DevTools protocol: open a page, act as a person, screenshot.

Used by the browser tests (console errors, non-blank canvas, moving the slider changes the
picture) and to take the documentation screenshot::

    python -m otmm_qp.replay.browser PAGE.html OUT.png [--fragment "frame=200&controller=1"]

Needs Debian's ``chromium`` (or ``chromium-browser``/``google-chrome``) and ``websockets``.
"""

from __future__ import annotations

import argparse
import base64
import itertools
import json
import os
import re
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from otmm_qp.interrupt import stop_signals_unblocked

BROWSER_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


class BrowserError(RuntimeError):
    """The browser could not be started or did not answer."""


def find_chromium() -> str | None:
    """Path of a Chromium-family browser on PATH, or None."""
    for name in BROWSER_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


class Page:
    """One browser tab driven over a DevTools websocket session.

    Attributes:
        console_errors: Console ``error``/``assert`` messages, uncaught exceptions and
            ``error``-level log entries seen so far.
    """

    def __init__(self, socket: Any, session: str) -> None:
        self._socket = socket
        self._session = session
        self._ids = itertools.count(1)
        self.console_errors: list[str] = []

    def _event(self, message: dict[str, Any]) -> None:
        method, params = message.get("method"), message.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            texts = [str(a.get("value", a.get("description", ""))) for a in params.get("args", [])]
            self.console_errors.append("console: " + " ".join(texts))
        elif method == "Runtime.exceptionThrown":
            detail = params.get("exceptionDetails", {})
            text = detail.get("exception", {}).get("description") or detail.get("text", "")
            self.console_errors.append(f"exception: {text}")
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            entry = params["entry"]
            self.console_errors.append(f"log ({entry.get('source')}): {entry.get('text')}")

    def send(self, method: str, timeout: float = 60.0, **params: Any) -> dict[str, Any]:
        """Send a DevTools command and return its result (events seen meanwhile are kept)."""
        ident = next(self._ids)
        self._socket.send(
            json.dumps(
                {"id": ident, "method": method, "params": params, "sessionId": self._session}
            )
        )
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise BrowserError(f"no answer to {method} within {timeout:.0f} s")
            message = json.loads(self._socket.recv(timeout=remaining))
            if message.get("id") == ident:
                if "error" in message:
                    raise BrowserError(f"{method}: {message['error']}")
                return dict(message.get("result", {}))
            if message.get("sessionId") == self._session:
                self._event(message)

    def evaluate(self, expression: str, timeout: float = 60.0) -> Any:
        """Value of a JavaScript expression (promises awaited)."""
        result = self.send(
            "Runtime.evaluate",
            timeout=timeout,
            expression=expression,
            awaitPromise=True,
            returnByValue=True,
        )
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression[:60]}: {result['exceptionDetails'].get('text')}")
        return result.get("result", {}).get("value")

    def open(
        self, url: str, ready: str = "document.readyState === 'complete'", timeout: float = 60.0
    ) -> None:
        """Navigate and wait until the ``ready`` expression is true."""
        self.send("Page.navigate", url=url)
        deadline = time.monotonic() + timeout
        while not self.evaluate(f"Boolean({ready})"):
            if time.monotonic() > deadline:
                raise BrowserError(f"{url}: not ready after {timeout:.0f} s ({ready})")
            time.sleep(0.1)
        self.settle()

    def settle(self, frames: int = 3) -> None:
        """Let the page render a few animation frames."""
        self.evaluate(
            f"new Promise(r => {{ let n = {frames};"
            " const f = () => (--n > 0 ? requestAnimationFrame(f) : r(true));"
            " requestAnimationFrame(f); })"
        )

    def click(self, x: float, y: float) -> None:
        """A left mouse click at page coordinates [CSS px]."""
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def screenshot(self) -> bytes:
        """PNG of the viewport."""
        return base64.b64decode(self.send("Page.captureScreenshot", format="png")["data"])


@contextmanager
def chromium_page(
    width: int = 1000, height: int = 700, executable: str | None = None
) -> Iterator[Page]:
    """A fresh headless Chromium (own profile, no network needed) with one tab.

    Raises:
        BrowserError: No browser found, or it did not start.
    """
    from websockets.sync.client import connect

    binary = executable or find_chromium()
    if binary is None:
        raise BrowserError(f"no Chromium found (looked for {', '.join(BROWSER_NAMES)})")
    with tempfile.TemporaryDirectory(prefix="otmm-chromium-") as profile:
        process = _launch(binary, profile, width, height)
        try:
            endpoint = _devtools_endpoint(process)
            # keep draining the browser's stderr so a chatty browser never blocks on a full pipe
            threading.Thread(target=_drain, args=(process.stderr,), daemon=True).start()
            with connect(endpoint, max_size=None, open_timeout=30) as socket:
                yield _open_tab(socket, width, height)
        finally:
            _stop(process)


def _launch(binary: str, profile: str, width: int, height: int) -> subprocess.Popen[str]:
    """Start headless Chromium with its own ``profile`` folder, DevTools on a free port."""
    with stop_signals_unblocked():  # the browser inherits this thread's signal mask
        return _popen(binary, profile, width, height)


def _popen(binary: str, profile: str, width: int, height: int) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            binary,
            "--headless",
            "--no-sandbox",
            "--no-first-run",
            "--disable-gpu-sandbox",
            "--enable-unsafe-swiftshader",
            "--allow-file-access-from-files",
            f"--user-data-dir={profile}",
            "--remote-debugging-port=0",
            f"--window-size={width},{height}",
            "about:blank",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def _open_tab(socket: Any, width: int, height: int) -> Page:
    """Open a blank tab over ``socket``, enable its events and set the viewport [CSS px]."""
    target = _call(socket, 1, "Target.createTarget", url="about:blank")["targetId"]
    session = _call(socket, 2, "Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
    page = Page(socket, session)
    for domain in ("Page", "Runtime", "Log"):
        page.send(f"{domain}.enable")
    page.send(
        "Emulation.setDeviceMetricsOverride",
        width=width,
        height=height,
        deviceScaleFactor=1,
        mobile=False,
    )
    return page


def _stop(process: subprocess.Popen[str]) -> None:
    """Terminate the browser (kill it after 10 s) and close its stderr pipe."""
    process.terminate()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    if process.stderr is not None:
        process.stderr.close()


def _drain(stream: IO[str] | None) -> None:
    if stream is None:
        return
    try:
        for _ in stream:
            pass
    except (OSError, ValueError):  # closed by the owner
        pass


def _devtools_endpoint(process: subprocess.Popen[str]) -> str:
    assert process.stderr is not None
    deadline = time.monotonic() + 30
    lines = []
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        if not line:
            if process.poll() is not None:
                break
            continue
        lines.append(line)
        match = re.search(r"DevTools listening on (ws://\S+)", line)
        if match:
            return match.group(1)
    raise BrowserError("Chromium did not start: " + "".join(lines[-5:]).strip())


def _call(socket: Any, ident: int, method: str, **params: Any) -> dict[str, Any]:
    socket.send(json.dumps({"id": ident, "method": method, "params": params}))
    while True:
        message = json.loads(socket.recv(timeout=30))
        if message.get("id") == ident:
            if "error" in message:
                raise BrowserError(f"{method}: {message['error']}")
            return dict(message["result"])


def screenshot_replay(
    html: Path, png: Path, fragment: str = "", width: int = 1000, height: int = 700
) -> list[str]:
    """Open a replay page, wait until it is ready, write a PNG; returns console errors."""
    with chromium_page(width, height) as page:
        url = Path(html).resolve().as_uri() + (f"#{fragment}" if fragment else "")
        page.open(url, ready="window.replayReady === true")
        page.settle(5)
        png.parent.mkdir(parents=True, exist_ok=True)
        png.write_bytes(page.screenshot())
        return list(page.console_errors)


def main() -> int:
    """``python -m otmm_qp.replay.browser PAGE OUT.png [--fragment ...]``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("page", type=Path)
    parser.add_argument("png", type=Path)
    parser.add_argument("--fragment", default="", help="URL hash, e.g. 'frame=200&controller=1'")
    parser.add_argument("--width", type=int, default=1000)
    parser.add_argument("--height", type=int, default=700)
    args = parser.parse_args()
    errors = screenshot_replay(args.page, args.png, args.fragment, args.width, args.height)
    for error in errors:
        print(f"console error: {error}")
    print(f"screenshot: {args.png} ({os.path.getsize(args.png)} bytes)")
    return 1 if errors else 0


if __name__ == "__main__":
    raise SystemExit(main())
