"""A screenshot of a web page (the 3D view) taken with headless Chromium over the DevTools protocol.

``screenshot(url, "view.png")`` (or ``Browser`` for several pictures of one page) starts Chromium headless (``$CHROMIUM``, else ``chromium``,
``chromium-browser``, ``google-chrome`` on the PATH: Debian's ``chromium`` package) with
WebGL rendered in software (SwiftShader: no GPU, no display needed), opens ``url``, waits
until the page has drawn the same picture twice in a row (the scene has arrived over the
websocket and little moves: at most ``tolerance`` of the pixels change between two
looks, which lets a status line tick and an arm creep), hides pop-up notifications (viser says that WebGL runs in
software, which is true and beside the point in a picture) and writes a PNG.

The DevTools protocol is JSON over a websocket (``websockets``, which viser depends on).
Used by ``python -m rcci.view.replay --screenshot`` and ``examples/view_demo.py`` (the picture in
docs/viewer.png) and by tests/test_viewer.py.
"""
from __future__ import annotations

import base64
import io
import itertools
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
# software WebGL, headless, no first-run noise; --no-sandbox only where Chromium refuses without it (root)
FLAGS = ("--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run",
         "--no-default-browser-check", "--disable-extensions", "--disable-background-networking",
         "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio")
HIDE_CSS = ".mantine-Notifications-root { display: none !important; }"


class BrowserError(RuntimeError):
    """No Chromium to be found, or it did not start or answer in time."""


def find_chromium() -> str:
    """The Chromium (or Chrome) executable: ``$CHROMIUM``, else the first of BROWSERS on the PATH."""
    env = os.environ.get("CHROMIUM")
    if env:
        return env
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    raise BrowserError("no Chromium found (tried $CHROMIUM and " + ", ".join(BROWSERS) +
                       "); on Debian/Ubuntu: apt-get install chromium")


class _DevTools:
    """One page's DevTools connection: ``call(method, **params)`` returns the result."""

    def __init__(self, ws_url: str, timeout: float) -> None:
        from websockets.sync.client import connect

        self.ws = connect(ws_url, max_size=None, open_timeout=timeout)
        self.ids = itertools.count(1)
        self.timeout = timeout

    def call(self, method: str, **params) -> dict:
        i = next(self.ids)
        self.ws.send(json.dumps({"id": i, "method": method, "params": params}))
        deadline = time.monotonic() + self.timeout
        while True:
            msg = json.loads(self.ws.recv(timeout=max(0.01, deadline - time.monotonic())))
            if msg.get("id") == i:
                if "error" in msg:
                    raise BrowserError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def close(self) -> None:
        self.ws.close()


def _devtools_port(profile: Path, proc: subprocess.Popen, timeout: float) -> int:
    """The port Chromium chose (--remote-debugging-port=0 writes it to DevToolsActivePort)."""
    f = profile / "DevToolsActivePort"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise BrowserError(f"Chromium exited with code {proc.returncode} before it was ready")
        try:
            return int(f.read_text().split()[0])
        except (OSError, ValueError, IndexError):
            time.sleep(0.05)
    raise BrowserError(f"Chromium did not open its DevTools port within {timeout} s")


class Browser:
    """Headless Chromium with one page: ``open(url)``, ``capture()`` (the page stays open: a live view
    keeps updating between captures), ``close()``; a context manager."""

    def __init__(self, size: tuple[int, int] = (1200, 800), *, timeout: float = 30.0,
                 browser: str | None = None) -> None:
        exe = browser or find_chromium()
        self.size = size
        self.timeout = timeout
        self._profile = tempfile.TemporaryDirectory(prefix="rci-chromium-")
        w, h = size
        argv = [exe, *FLAGS, f"--user-data-dir={self._profile.name}", "--remote-debugging-port=0",
                f"--window-size={w},{h}", "about:blank"]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            argv.insert(1, "--no-sandbox")
        # a session of its own: close() ends Chromium's helper processes too, which otherwise may
        # still write into the profile while it is removed
        self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, start_new_session=True)
        self._dt: _DevTools | None = None
        self.url = ""
        try:
            port = _devtools_port(Path(self._profile.name), self.proc, timeout)
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=timeout) as r:
                pages = [t for t in json.load(r) if t.get("type") == "page"]
            if not pages:
                raise BrowserError("Chromium has no page open")
            self._dt = _DevTools(pages[0]["webSocketDebuggerUrl"], timeout)
            self._dt.call("Emulation.setDeviceMetricsOverride", width=w, height=h, deviceScaleFactor=1,
                          mobile=False)
        except BaseException:
            self.close()
            raise

    def open(self, url: str) -> None:
        """Load ``url`` and wait until the document is complete; hide pop-up notifications."""
        dt = self._dt
        deadline = time.monotonic() + self.timeout
        dt.call("Page.navigate", url=url)
        while dt.call("Runtime.evaluate", expression="document.readyState",
                      returnByValue=True)["result"].get("value") != "complete":
            if time.monotonic() > deadline:
                raise BrowserError(f"{url} did not load within {self.timeout} s")
            time.sleep(0.05)
        self.url = url
        self._loaded = time.monotonic()
        hide = ("(() => { const s = document.createElement('style'); s.textContent = " + json.dumps(HIDE_CSS) +
                "; document.head.appendChild(s); })()")
        dt.call("Runtime.evaluate", expression=hide)

    def grab(self) -> bytes:
        """The page as it is now (PNG)."""
        return base64.b64decode(self._dt.call("Page.captureScreenshot", format="png")["data"])

    def capture(self, out: str | os.PathLike | None = None, *, settle: float = 0.6, tolerance: float = 0.003,
                min_wait: float = 1.0) -> bytes:
        """PNG of the page once steady: two looks ``settle`` s apart differ in at most ``tolerance`` of the
        pixels, at least ``min_wait`` s after it loaded; also written to ``out``. BrowserError after ``timeout``."""
        deadline = time.monotonic() + self.timeout
        last = None
        while True:
            time.sleep(settle)
            png = self.grab()
            now = pixels(png)
            if _changed(last, now) <= tolerance and time.monotonic() - self._loaded >= min_wait:
                break
            if time.monotonic() > deadline:
                raise BrowserError(f"{self.url}: the picture did not settle within {self.timeout} s")
            last = now
        if out is not None:
            Path(out).write_bytes(png)
        return png

    def close(self) -> None:
        if self._dt is not None:
            try:
                self._dt.close()
            except Exception:  # noqa: BLE001 - the browser may already be gone
                pass
            self._dt = None
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)     # its helpers (renderer, GPU, crash handler)
        except (ProcessLookupError, PermissionError):
            pass
        for attempt in range(20):                         # a helper's last write may still land
            try:
                self._profile.cleanup()
                return
            except OSError:
                time.sleep(0.05)
        shutil.rmtree(self._profile.name, ignore_errors=True)

    def __enter__(self) -> "Browser":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def screenshot(url: str, out: str | os.PathLike | None = None, *, size: tuple[int, int] = (1200, 800),
               settle: float = 0.6, tolerance: float = 0.003, timeout: float = 30.0, min_wait: float = 1.0,
               browser: str | None = None) -> bytes:
    """PNG bytes of ``url`` rendered at ``size`` (pixels) once the picture is steady (``Browser.capture``);
    also written to ``out``."""
    with Browser(size, timeout=timeout, browser=browser) as b:
        b.open(url)
        return b.capture(out, settle=settle, tolerance=tolerance, min_wait=min_wait)


def pixels(png: bytes) -> np.ndarray:
    """The RGB pixels (H, W, 3) of a PNG."""
    from PIL import Image

    with Image.open(io.BytesIO(png)) as im:
        return np.asarray(im.convert("RGB"))


def _changed(a: np.ndarray | None, b: np.ndarray) -> float:
    """Fraction of the pixels that differ between two pictures (1 if there is no first one)."""
    if a is None or a.shape != b.shape:
        return 1.0
    return float(np.mean(np.any(a != b, axis=2)))
