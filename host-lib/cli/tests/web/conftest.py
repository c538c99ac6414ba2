"""Shared set-up of the web tests: `kerfmeter --sim serve` on a free loopback port, and a
headless Chromium driven by Selenium.

`cargo xtask test-browser` runs these tests with KERFMETER set to the built binary and CHROMIUM
and CHROMEDRIVER to Debian's chromium and chromium-driver (it installs them when missing).
"""

import functools
import os
import pathlib
import re
import subprocess
import threading

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[4]
"""The workspace root."""

# The server prints the address it listens on; with port 0 that is the only way to learn it.
ADDRESS = re.compile(r"\b127\.0\.0\.1:(\d+)\b")
STARTUP_TIMEOUT_S = 60


def kerfmeter_bin():
    path = os.environ.get("KERFMETER")
    if not path:
        pytest.fail("set KERFMETER to the kerfmeter binary (`cargo xtask test-browser` does)")
    return path


@functools.cache
def serve_flags():
    """`serve`'s flags, from its --help: `--db` arrives with the history store."""
    out = subprocess.run([kerfmeter_bin(), "serve", "--help"], capture_output=True, text=True)
    if out.returncode != 0:
        pytest.fail(f"{kerfmeter_bin()} has no working `serve` command:\n{out.stderr}")
    return set(re.findall(r"--[a-z][a-z-]*", out.stdout))


class Server:
    """One `kerfmeter --sim serve` process; `start()` again after `stop()` restarts it on the
    same port (the page must reconnect by itself)."""

    def __init__(self, tmp_path, realtime, extra=()):
        self.db = tmp_path / "history.sqlite"
        self.realtime = realtime
        self.extra = list(extra)
        self.port = 0
        self.proc = None
        self.output = []

    @property
    def url(self):
        return f"http://127.0.0.1:{self.port}/"

    @property
    def rpc_url(self):
        return f"ws://127.0.0.1:{self.port}/rpc"

    def command(self):
        cmd = [kerfmeter_bin(), "--sim"]
        if self.realtime:
            cmd.append("--sim-realtime")
        cmd += ["serve", "--listen", f"127.0.0.1:{self.port}"]
        if "--db" in serve_flags():
            cmd += ["--db", str(self.db)]
        return cmd + self.extra

    def start(self):
        found = threading.Event()
        self.proc = subprocess.Popen(
            self.command(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            errors="replace",
        )

        def read(proc):
            for line in proc.stdout:
                self.output.append(line.rstrip("\n"))
                match = ADDRESS.search(line)
                if match and not found.is_set():
                    self.port = int(match.group(1))
                    found.set()

        threading.Thread(target=read, args=(self.proc,), daemon=True).start()
        if not found.wait(STARTUP_TIMEOUT_S):
            self.stop()
            pytest.fail(f"the server printed no address: {self.log()}")

    def stop(self):
        if self.proc is None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc = None

    def log(self):
        return "\n".join(self.output[-40:])


@pytest.fixture
def server(tmp_path):
    """A server on the twin in real time, so that a run streams its progress as a device's
    would."""
    s = Server(tmp_path, realtime=True)
    s.start()
    yield s
    s.stop()


@pytest.fixture
def fast_server(tmp_path):
    """A server on the twin in simulated time (a run takes well under a second)."""
    s = Server(tmp_path, realtime=False)
    s.start()
    yield s
    s.stop()


@pytest.fixture
def token_server(tmp_path):
    """A server that wants a token from its clients."""
    s = Server(tmp_path, realtime=False, extra=["--token", TOKEN])
    s.start()
    yield s
    s.stop()


TOKEN = "page-test-token-0123456789"


@pytest.fixture
def motor_shaft_server(tmp_path):
    """A server on a twin whose encoder is on the motor shaft: it comes up waiting for the user
    to confirm the hub at its zero mark."""
    s = Server(tmp_path, realtime=False, extra=["--sim-encoder-on-motor-shaft"])
    s.start()
    yield s
    s.stop()
