"""Every stream Kerfmeter's Ruida driver sends (`kerfmeter::ruida`, the job loop's Ruida cutter)
decoded by MeerK40t 0.9.9100's own Ruida emulator: the gauge, a job of two layers with arcs,
the prongs' moves, and the streams of the failure cases (a lost program packet, a job refused,
a late acknowledgement), each exactly as the simulated controller received it over UDP.

The host library's `ruida_streams` example runs the scenarios of `host-lib/kerfmeter/tests/
ruida.rs` on the simulated controller and writes the datagrams it received with what each
stream was meant to do (`cargo xtask test-python` builds it and names it in
KERFMETER_RUIDA_STREAMS; without it the test builds it with cargo). Every datagram is fed to
MeerK40t's emulator in order (register reads included) and must be ACKed and split into
commands it knows; the job it collected is executed against a recording driver, and what it
read back is compared with the plan: every move and cut to the µm (arcs flattened within 1 µm
by the driver), the laser off on every travel, each layer's speed and powers, the direct moves
of the head and Z, the stop after a failure, and the gauge where it was asked.

ruida-pa 0.23.0 (KERFMETER_RUIDA_PA) reads the same programs and the prongs' direct moves too:
nothing flagged, the file sum OK, every move and cut, speed and power as planned, the moves as
absolute MACHINE moves.
"""

import json
import os
import subprocess
from pathlib import Path

import pytest

pytest.importorskip("meerk40t.ruida.emulator")
from test_ruida_peer import ACK, POWER_STEP, controller, send  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]


def streams_program():
    path = os.environ.get("KERFMETER_RUIDA_STREAMS")
    if path:
        return [path]
    subprocess.run(
        ["cargo", "build", "-q", "-p", "kerfmeter", "--features", "sim", "--example", "ruida_streams"],
        cwd=ROOT,
        check=True,
    )
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return [str(target / "debug" / "examples" / "ruida_streams")]


@pytest.fixture(scope="module")
def streams(tmp_path_factory):
    out = tmp_path_factory.mktemp("ruida-driver") / "streams.json"
    subprocess.run(streams_program() + [str(out)], check=True)
    return json.loads(out.read_text())


SCENARIOS = ["gauge", "job", "lower", "lift", "lost_packet", "refused", "late_ack"]


def scenario(streams, name):
    return next(s for s in streams["scenarios"] if s["name"] == name)


def replay(s):
    """MeerK40t's emulator fed every datagram; its recording driver after the job ran."""
    emulator, driver, replies, log = controller()
    for datagram in s["datagrams"]:
        assert send(emulator, replies, datagram) == ACK, log[-3:]
    while emulator.job.buffer:
        emulator.job.execute()
    failures = [line for line in log if "Failure" in line or "Unknown" in line]
    assert not failures, failures
    return driver


def cut_layers(s):
    return [layer for step in s["plan"] if step["kind"] == "cut" for layer in step["layers"]]


def check_plots(driver, layers):
    assert len(driver.plots) == len(layers)
    for layer, plot in zip(layers, driver.plots):
        assert plot["speed"] == pytest.approx(layer["speed_mm_per_s"], abs=0.001)
        assert abs(plot["min_power"] - layer["min_power_percent"]) <= POWER_STEP
        assert abs(plot["max_power"] - layer["max_power_percent"]) <= POWER_STEP
        planned = []
        for path in layer["paths_mm"]:
            planned.append((path[0], 0))
            planned.extend((point, 1) for point in path[1:])
        assert len(plot["steps"]) == len(planned)
        for (x_um, y_um, on), ((x_mm, y_mm), laser) in zip(plot["steps"], planned):
            assert on == laser, "a travel with the laser on, or a cut with it off"
            assert abs(x_um - x_mm * 1000) <= 0.5 + 1e-6
            assert abs(y_um - y_mm * 1000) <= 0.5 + 1e-6


def test_every_scenario_is_one_the_test_knows(streams):
    assert streams["magic"] == 0x88
    assert [s["name"] for s in streams["scenarios"]] == SCENARIOS


@pytest.mark.parametrize("name", ["gauge", "job"])
def test_meerk40t_reads_the_drivers_programs_as_planned(streams, name):
    s = scenario(streams, name)
    assert s["ok"]
    driver = replay(s)
    check_plots(driver, cut_layers(s))
    assert driver.ended == 1
    assert driver.resets == 0, "no stop on a stream that went well"


def test_the_job_has_two_layers_and_its_arcs_are_flattened_within_a_micrometre(streams):
    layers = cut_layers(scenario(streams, "job"))
    settings = [(layer["speed_mm_per_s"], layer["max_power_percent"]) for layer in layers]
    assert settings == [(10, 80), (20, 35)]
    (circle,) = layers[1]["paths_mm"]
    assert len(circle) > 100
    for a, b in zip(circle, circle[1:]):
        mid = [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]
        r = ((mid[0] - 500) ** 2 + (mid[1] - 60) ** 2) ** 0.5
        assert 10 - r <= 0.001 + 1e-9


def test_the_gauge_lands_where_it_was_asked(streams):
    s = scenario(streams, "gauge")
    driver = replay(s)
    steps = driver.plots[0]["steps"]
    (layer,) = cut_layers(s)
    holes, at = [], 0
    # The holes are cut first (the spiral's inner contours), each a closed ring of chords.
    for path in layer["paths_mm"][:2]:
        ring = steps[at : at + len(path)]
        at += len(path)
        xs, ys = [p[0] for p in ring], [p[1] for p in ring]
        holes.append([(min(xs) + max(xs)) / 2000, (min(ys) + max(ys)) / 2000])
    centre = [(holes[0][i] + holes[1][i]) / 2 for i in (0, 1)]
    assert centre == pytest.approx(streams["gauge_at_mm"], abs=0.002)


@pytest.mark.parametrize("name", ["lower", "lift"])
def test_the_prongs_moves_are_the_direct_moves_planned(streams, name):
    s = scenario(streams, name)
    assert s["ok"]
    driver = replay(s)
    assert driver.plots == []
    xy = [(m["x_mm"], m["y_mm"]) for m in s["plan"] if m["kind"] == "move_xy"]
    z = [m["z_mm"] for m in s["plan"] if m["kind"] == "move_z"]
    assert [tuple(float(v.removesuffix("mm")) for v in m) for m in driver.moves] == xy
    assert [v / 1000 for (axis, v) in driver.axes if axis == "z"] == pytest.approx(z, abs=0.0005)


@pytest.mark.parametrize("name", ["lost_packet", "refused", "late_ack"])
def test_a_failed_stream_is_decodable_and_ends_with_a_stop(streams, name):
    s = scenario(streams, name)
    assert not s["ok"]
    driver = replay(s)
    assert driver.resets >= 1, "D8 01 after the failure"
    # Whatever MeerK40t collected is the plan's, laser off on every travel: a lost packet leaves
    # a program without its end, a refused one is the plan whole (the controller refused it).
    if name == "refused":
        check_plots(driver, cut_layers(s))
    for plot in driver.plots:
        assert all(on in (0, 1) for (_, _, on) in plot["steps"])


def swizzled_payloads(s, program):
    """The datagrams' swizzled payloads (checksum left out): the program's, or the direct moves'."""
    from meerk40t.ruida.rdjob import decode_bytes

    out = []
    for datagram in s["datagrams"]:
        payload = bytes.fromhex(datagram)[2:]
        first = decode_bytes(payload, magic=0x88)[0]
        direct = first in (0xDA, 0xD8, 0xCE, 0xD9)
        if direct != program and (program or first == 0xD9):
            out.append(payload)
    return b"".join(out)


@pytest.mark.parametrize("name", ["gauge", "job"])
def test_ruida_pa_reads_the_drivers_programs_as_planned(streams, name, tmp_path):
    from test_ruida_peer import RPA_POWER, RPA_SPEED, RPA_XY, planned_steps, rpa_decode

    s = scenario(streams, name)
    messages, flagged, lines = rpa_decode(tmp_path, name, swizzled_payloads(s, True))
    assert not flagged, flagged
    assert messages[-1] == "EOF"
    assert any("Checksum OK" in line for line in lines)
    layers = cut_layers(s)
    steps = [RPA_XY.match(m).groups() for m in messages if RPA_XY.match(m)]
    planned = [step for layer in layers for step in planned_steps(layer)]
    assert len(steps) == len(planned)
    for (kind, x, y), ((x_mm, y_mm), laser) in zip(steps, planned):
        assert kind == ("CUT" if laser else "MOVE")
        assert abs(float(x) - x_mm) <= 0.0005 + 1e-9
        assert abs(float(y) - y_mm) <= 0.0005 + 1e-9
    speeds = [float(RPA_SPEED.match(m).group(1)) for m in messages if RPA_SPEED.match(m)]
    assert speeds == [layer["speed_mm_per_s"] for layer in layers]
    powers = [float(RPA_POWER.match(m).group(2)) for m in messages if RPA_POWER.match(m)]
    expected = [layer[f"{w}_power_percent"] for layer in layers for w in ("min", "max")]
    assert powers == pytest.approx(expected, abs=0.05 + POWER_STEP)


def test_ruida_pa_reads_the_prongs_moves_as_absolute(streams, tmp_path):
    from test_ruida_peer import rpa_decode

    s = scenario(streams, "lower")
    messages, flagged, _ = rpa_decode(tmp_path, "lower", swizzled_payloads(s, False))
    assert not flagged, flagged
    expected = []
    for m in s["plan"]:
        if m["kind"] == "move_xy":
            expected.append(f"JOG_XY MACHINE X={m['x_mm']:.3f}mm Y={m['y_mm']:.3f}mm")
        elif m["kind"] == "move_z":
            expected.append(f"JOG_Z MACHINE Z={m['z_mm']:.3f}mm")
    assert messages == expected
