"""Shared fixtures of the judge's tests: evo's command lines, to test our files and figures against evo itself (the
``evo`` package of the dev extra; the tests that need it are skipped where it is not installed)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest


def _evo_tool(name: str) -> str | None:
    beside = Path(sys.executable).with_name(name)  # the venv's console scripts sit beside its interpreter
    return str(beside) if beside.is_file() else shutil.which(name)


@pytest.fixture
def evo(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., dict]:
    """``evo(tool, *args)``: run evo's ``tool`` (``evo_traj``, ``evo_ape``, ``evo_rpe``) with its own settings folder
    (``HOME`` in a temporary folder); returns ``{"stdout": ..., "stats": ...}``, ``stats`` read from the results
    file that ``--save_results`` wrote (evo_ape / evo_rpe), with its arrays (``"arrays"``: name -> array, e.g.
    ``error_array``). Fails with evo's output when evo fails."""
    if _evo_tool("evo_ape") is None:
        pytest.skip("evo is not installed (pip install -c constraints.txt -e '.[dev]')")
    home = tmp_path_factory.mktemp("evo-home")
    env = {"HOME": str(home), "PATH": str(Path(sys.executable).parent) + ":/usr/bin:/bin", "MPLBACKEND": "Agg"}

    def run(tool: str, *args: str) -> dict:
        out: dict = {}
        extra: list[str] = []
        if tool in ("evo_ape", "evo_rpe"):
            results = home / f"{tool}-{len(list(home.glob('*.zip')))}.zip"
            extra = ["--save_results", str(results)]
        done = subprocess.run([_evo_tool(tool) or tool, *args, *extra], capture_output=True, text=True, env=env,
                              timeout=120)  # fmt: skip
        assert done.returncode == 0, f"{tool} {' '.join(args)} failed:\n{done.stdout}\n{done.stderr}"
        out["stdout"] = done.stdout
        if extra:
            import io

            import numpy as np

            with zipfile.ZipFile(extra[1]) as z:
                out["stats"] = json.loads(z.read("stats.json"))
                out["arrays"] = {Path(n).stem: np.load(io.BytesIO(z.read(n))) for n in z.namelist()
                                 if n.endswith(".npy")}  # fmt: skip
        return out

    return run


# ------------------------------------------------------------------------------------------- a headless browser
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
BROWSER_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-default-apps", "--remote-debugging-port=0")  # fmt: skip


class BrowserPage:
    """A page of a headless Chromium driven through the DevTools protocol (over ``websockets``): what it loaded
    (``requests``: every URL it asked for), the uncaught script errors and console errors it reported
    (``errors``), and ``evaluate`` / ``click`` on it."""

    def __init__(self, socket, session: str) -> None:
        self.socket, self.session, self.next_id = socket, session, 0
        self.requests: list[str] = []
        self.errors: list[str] = []
        self.events: list[str] = []

    def _handle(self, message: dict) -> None:
        method, params = message.get("method"), message.get("params", {})
        if method is None:
            return
        self.events.append(method)
        if method == "Network.requestWillBeSent":
            self.requests.append(params["request"]["url"])
        elif method == "Runtime.exceptionThrown":
            details = params["exceptionDetails"]
            self.errors.append(str(details.get("exception", {}).get("description") or details.get("text")))
        elif method == "Runtime.consoleAPICalled" and params.get("type") == "error":
            self.errors.append("console.error: " + " ".join(str(a.get("value")) for a in params.get("args", [])))
        elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
            self.errors.append("log: " + params["entry"].get("text", ""))

    def send(self, method: str, params: dict | None = None, session: bool = True) -> dict:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = self.session
        self.socket.send(json.dumps(message))
        while True:
            reply = json.loads(self.socket.recv(timeout=60))
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self._handle(reply)

    def wait_for(self, event: str, timeout: float = 60.0) -> None:
        import time

        end = time.monotonic() + timeout
        while event not in self.events:
            remaining = end - time.monotonic()
            assert remaining > 0, f"no {event} within {timeout} s (got {sorted(set(self.events))})"
            self._handle(json.loads(self.socket.recv(timeout=remaining)))

    def open(self, path: Path) -> None:
        """Load ``path`` and wait for its load event, then let its scripts settle."""
        for domain in ("Page", "Runtime", "Network", "Log"):
            self.send(f"{domain}.enable")
        self.send("Page.navigate", {"url": path.resolve().as_uri()})
        self.wait_for("Page.loadEventFired")
        self.evaluate("new Promise(r => setTimeout(r, 100))")

    def evaluate(self, expression: str):
        result = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                "awaitPromise": True})  # fmt: skip
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def click(self, selector: str) -> None:
        """A real mouse click (press and release) at the centre of the first element ``selector`` matches."""
        box = self.evaluate(f"(() => {{const e = document.querySelector({json.dumps(selector)});"
                            "e.scrollIntoView({block: 'center'}); const r = e.getBoundingClientRect();"
                            "return [r.x + r.width / 2, r.y + r.height / 2];})()")
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", {"type": kind, "x": box[0], "y": box[1], "button": "left",
                                                   "clickCount": 1})  # fmt: skip
        self.evaluate("new Promise(r => setTimeout(r, 50))")


@pytest.fixture
def browser_page(tmp_path_factory: pytest.TempPathFactory):
    """A fresh headless Chromium page (:class:`BrowserPage`); skipped where no Chromium is installed (``.ci/run``
    installs Debian's ``chromium``)."""
    import re
    import time

    from websockets.sync.client import connect

    binary = next((b for b in BROWSERS if shutil.which(b)), None)
    if binary is None:
        pytest.skip("no Chromium here (Debian: apt-get install chromium; .ci/run installs it)")
    profile = tmp_path_factory.mktemp("chromium-profile")
    process = subprocess.Popen([shutil.which(binary), *BROWSER_FLAGS, f"--user-data-dir={profile}", "about:blank"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        end, url, seen = time.monotonic() + 60, None, []
        while url is None and time.monotonic() < end:
            line = process.stderr.readline()
            if not line and process.poll() is not None:
                break
            seen.append(line)
            found = re.search(r"DevTools listening on (ws://\S+)", line)
            url = found.group(1) if found else None
        assert url, "Chromium did not start:\n" + "".join(seen[-20:])
        import threading

        threading.Thread(target=process.stderr.read, daemon=True).start()  # keep its pipe from filling up
        with connect(url, max_size=None, open_timeout=30) as socket:
            page = BrowserPage(socket, "")
            target = page.send("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
            page.session = page.send("Target.attachToTarget", {"targetId": target, "flatten": True},
                                     session=False)["sessionId"]  # fmt: skip
            yield page
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
