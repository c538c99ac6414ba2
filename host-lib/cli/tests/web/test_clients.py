"""The WebSocket clients of docs/server.md (examples/clients/), each run against `kerfmeter --sim serve`:
a measurement through run_kerfmeter, then the same kerf back from get_kerf_value."""

import re
import subprocess
import sys

import pytest

from conftest import ROOT

CLIENTS = ROOT / "examples" / "clients"
TIMEOUT_S = 120


def node_command():
    """`node`, with --experimental-websocket before Node 22 (which has WebSocket built in)."""
    try:
        version = subprocess.run(
            ["node", "--version"], capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.fail("node is missing: install Node.js 20 or later (https://nodejs.org)")
    major = int(version.strip().lstrip("v").split(".")[0])
    if major < 20:
        pytest.fail(f"node {version.strip()} has no WebSocket: install Node.js 20 or later")
    return ["node"] if major >= 22 else ["node", "--experimental-websocket"]


def check_output(server, cmd):
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert done.returncode == 0, (
        f"{cmd} failed:\n{done.stdout}\n{done.stderr}\nserver:\n{server.log()}"
    )
    kerf = re.search(r"^kerf (\d+\.\d) µm$", done.stdout, re.M)
    last = re.search(r"^last (\d+\.\d) µm$", done.stdout, re.M)
    assert kerf and last, f"unexpected output of {cmd}:\n{done.stdout}"
    # The twin cuts 150 µm gauges by default: a reading, not an error turned into a number.
    assert 100 < float(kerf.group(1)) < 200
    # The same number, printed from an f64 and from the device's f32: equal to the print's 0.1.
    assert abs(float(kerf.group(1)) - float(last.group(1))) <= 0.1, (
        "get_kerf_value does not return the run's kerf"
    )


def test_python_client(fast_server):
    check_output(fast_server, [sys.executable, str(CLIENTS / "client.py"), fast_server.rpc_url])


def test_javascript_client(fast_server):
    cmd = node_command() + [str(CLIENTS / "client.mjs"), fast_server.rpc_url]
    check_output(fast_server, cmd)


@pytest.mark.parametrize("name", ["client.py", "client.mjs"])
def test_clients_fail_loudly_without_a_server(tmp_path, name):
    """A client that cannot reach the server must not exit 0 as if it had measured."""
    url = "ws://127.0.0.1:9/rpc"  # the discard port: nothing listens there
    cmd = [sys.executable] if name.endswith(".py") else node_command()
    done = subprocess.run(
        cmd + [str(CLIENTS / name), url], capture_output=True, text=True, timeout=TIMEOUT_S
    )
    assert done.returncode != 0
    assert "kerf" not in done.stdout
