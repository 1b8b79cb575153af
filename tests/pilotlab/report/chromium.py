"""Drive headless Chromium over the DevTools protocol on a pipe (`--remote-debugging-pipe`).

Chromium reads JSON commands from file descriptor 3 and writes replies and events to descriptor 4,
each message ended by a NUL byte. That needs nothing beyond the standard library (no websocket
client, no Playwright) and no TCP port. `open_page(url)` loads a page and collects every console
error, uncaught exception and log error; `Page.evaluate` runs JavaScript; `Page.screenshot` saves a
full-page PNG.
"""
from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import subprocess
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--remote-debugging-pipe")


class BrowserError(RuntimeError):
    """Chromium did not answer as the protocol says (it exited, or a command failed or timed out)."""


class Pipe:
    """One DevTools connection: numbered commands out, replies and events in."""

    def __init__(self, write_fd: int, read_fd: int, timeout: float):
        self.write_fd, self.read_fd, self.timeout = write_fd, read_fd, timeout
        self.buffer, self.next_id, self.events = b"", 0, []

    def call(self, method: str, params: dict | None = None, session: str | None = None) -> dict:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        while True:
            reply = self.receive()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise BrowserError(f"{method} failed: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str) -> dict:
        for event in self.events:
            if event.get("method") == method:
                return event
        while True:
            event = self.receive()
            self.events.append(event)
            if event.get("method") == method:
                return event

    def receive(self) -> dict:
        deadline = time.monotonic() + self.timeout
        while b"\0" not in self.buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([self.read_fd], [], [], remaining)[0]:
                raise BrowserError(f"chromium sent nothing for {self.timeout:.0f} s")
            chunk = os.read(self.read_fd, 1 << 20)
            if not chunk:
                raise BrowserError("chromium closed the DevTools pipe (it exited)")
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)


class Page:
    def __init__(self, pipe: Pipe, session: str):
        self.pipe, self.session = pipe, session

    def evaluate(self, expression: str) -> Any:
        result = self.pipe.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                     "awaitPromise": True}, self.session)
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression!r} threw: {result['exceptionDetails']}")
        return result["result"].get("value")

    def screenshot(self, path: Path, width: int = 1280) -> Path:
        height = int(self.evaluate("document.documentElement.scrollHeight"))
        self.pipe.call("Emulation.setDeviceMetricsOverride",
                       {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, self.session)
        shot = self.pipe.call("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True}, self.session)
        path.write_bytes(base64.b64decode(shot["data"]))
        return path

    def problems(self) -> list[str]:
        """Console errors, uncaught exceptions and error log entries (CSP violations, failed loads)."""
        found = []
        for event in self.pipe.events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                found.append(f"exception: {details.get('exception', {}).get('description') or details.get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                found.append("console.error: " + " ".join(str(a.get("value", a.get("description"))) for a in params["args"]))
            elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
                found.append(f"log: {params['entry'].get('text')} ({params['entry'].get('url', '')})")
        return found

    def console_messages(self) -> list[str]:
        return [" ".join(str(a.get("value")) for a in e["params"]["args"])
                for e in self.pipe.events if e.get("method") == "Runtime.consoleAPICalled"]


@contextmanager
def open_page(url: str, timeout: float = 30.0) -> Iterator[Page]:
    """Start a fresh headless Chromium (new profile), load `url` and wait for its load event."""
    to_browser_read, to_browser_write = os.pipe()
    from_browser_read, from_browser_write = os.pipe()

    def wire_descriptors():                      # in the child: fd 3 = commands in, fd 4 = replies out
        commands, replies = (fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_browser_read, from_browser_write))
        os.dup2(commands, 3)                     # (via fds >= 10, so that neither end overwrites the other)
        os.dup2(replies, 4)

    with tempfile.TemporaryDirectory(prefix="pilotlab-chromium-") as profile:
        process = subprocess.Popen([str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                   close_fds=False, preexec_fn=wire_descriptors,   # only fds 3, 4 are inheritable
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_browser_read)
        os.close(from_browser_write)
        pipe = Pipe(to_browser_write, from_browser_read, timeout)
        try:
            yield _load(pipe, url)
        finally:
            _close(pipe, process)


def _load(pipe: Pipe, url: str) -> Page:
    target = pipe.call("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = pipe.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Runtime", "Log", "Page"):
        pipe.call(f"{domain}.enable", session=session)
    pipe.events.clear()                           # about:blank's own events are not the page's
    navigation = pipe.call("Page.navigate", {"url": url}, session)
    if navigation.get("errorText"):
        raise BrowserError(f"chromium could not open {url}: {navigation['errorText']}")
    pipe.wait_for("Page.loadEventFired")
    return Page(pipe, session)


def _close(pipe: Pipe, process: subprocess.Popen) -> None:
    try:
        pipe.call("Browser.close")
    except (BrowserError, OSError):
        pass
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    os.close(pipe.write_fd)
    os.close(pipe.read_fd)
