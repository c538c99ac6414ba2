"""Kerfmeter's Ruida encoder (the `kerfmeter-ruida` crate) checked by an implementation nobody
here wrote: MeerK40t 0.9.9100's own Ruida code (`meerk40t.ruida.emulator.RuidaEmulator`, which
checks each packet's checksum, unswizzles it and splits it into commands, and
`meerk40t.ruida.rdjob.RDJob`, which executes them).

The crate's `encode` example writes every stream (`cargo xtask test-python` builds it and names
it in KERFMETER_RUIDA_ENCODER; without it the test builds it with cargo). Each program's packets
are fed to MeerK40t's emulator as a controller receives them on UDP port 50200, the job it
collected is executed against a recording driver, and what MeerK40t read back is compared with
the plan: every move and cut to the µm, every travel with the laser off, the speeds, the powers
(within one 2^14 step: 10 % reads back as 9.998 %), the file sum and the end of file, and the
gauge where it was asked. The direct commands (head, Z and U moves, stop, register reads) go
through the same emulator; its answers to the register reads are read back by the crate.

A second decoder, ruida-pa 0.23.0's `rpa` (its own venv; `cargo xtask test-python` names it in
KERFMETER_RUIDA_PA), reads each program as an `.rd` file and must find the same moves, cuts,
speeds, powers and file sum, with nothing flagged; the two decoders disagree on some commands
(`docs/ruida.md`), and the encoder writes none of those.
"""

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

emulator_module = pytest.importorskip("meerk40t.ruida.emulator")
from meerk40t.core.units import UNITS_PER_uM  # noqa: E402
from meerk40t.ruida.rdjob import RDJob, decode_bytes, decodeu35, parse_commands  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
MEERK40T_VERSION = "0.9.9100"
ACK, NAK = 0xCC, 0xCF
# One 14-bit power step, percent.
POWER_STEP = 100 / 16384


def test_the_decoder_is_the_version_the_docs_name():
    from importlib.metadata import version

    assert version("meerk40t") == MEERK40T_VERSION
    assert f"MeerK40t {MEERK40T_VERSION}" in (ROOT / "docs" / "ruida.md").read_text()


def encoder():
    path = os.environ.get("KERFMETER_RUIDA_ENCODER")
    if path:
        return [path]
    subprocess.run(
        ["cargo", "build", "-q", "-p", "kerfmeter-ruida", "--example", "encode"],
        cwd=ROOT,
        check=True,
    )
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return [str(target / "debug" / "examples" / "encode")]


@pytest.fixture(scope="module")
def streams(tmp_path_factory):
    out = tmp_path_factory.mktemp("ruida") / "streams.json"
    subprocess.run(encoder() + [str(out)], check=True)
    return json.loads(out.read_text())


class Micrometres:
    """MeerK40t's units to µm and back (the emulator's device matrix)."""

    def transform_point(self, point):
        return [point[0] / UNITS_PER_uM, point[1] / UNITS_PER_uM]

    def point_in_inverse_space(self, point):
        return [point[0] * UNITS_PER_uM, point[1] * UNITS_PER_uM]


class RecordingDriver:
    """What MeerK40t's emulator and job tell a laser to do, recorded."""

    def __init__(self):
        self.job = None
        self.plots = []
        self.ended = 0
        self.moves = []
        self.axes = []
        self.resets = 0
        self.position_um = (0, 0)

    def plot(self, plotcut):
        points = plotcut._points
        self.plots.append(
            {
                "speed": plotcut.settings["speed"],
                "min_power": self.job.power1_min,
                "max_power": self.job.power1_max,
                # The first point starts the plot; each later one is reached with the laser
                # on (1) or off (0).
                "steps": [(x, y, on) for (x, y), on in zip(points[1:], plotcut._powers)],
            }
        )

    def plot_start(self):
        self.ended += 1

    def move_abs(self, x, y):
        self.moves.append((x, y))

    def axis(self, name, value):
        self.axes.append((name, value / UNITS_PER_uM))

    def reset(self):
        self.resets += 1

    def home(self):
        pass

    def status(self):
        return self.position_um, "idle", None


class Device:
    """The emulator's device: a driver, a spooler that keeps the job, a position."""

    def __init__(self):
        self.driver = RecordingDriver()
        self.spooler = self
        self.current = (0, 0)
        self.jobs = []

    def send(self, job, prevent_duplicate=False):
        if job not in self.jobs:
            self.jobs.append(job)


def controller():
    """MeerK40t's emulated controller, with its replies and log kept."""
    device = Device()
    emulator = emulator_module.RuidaEmulator(device, Micrometres())
    replies, log = [], []
    emulator.reply = replies.append
    emulator.channel = log.append
    device.driver.job = emulator.job
    return emulator, device.driver, replies, log


def send(emulator, replies, packet_hex):
    """Send one packet; MeerK40t's first reply to it, unswizzled."""
    before = len(replies)
    emulator.checksum_write(bytes.fromhex(packet_hex))
    assert len(replies) > before, "MeerK40t did not answer the packet"
    return emulator.unswizzle(replies[before])[0]


def run_program(program):
    emulator, driver, replies, log = controller()
    for packet in program["packets"]:
        assert len(bytes.fromhex(packet)) <= 1024
        assert send(emulator, replies, packet) == ACK, log[-3:]
    while emulator.job.buffer:
        emulator.job.execute()
    failures = [line for line in log if "Failure" in line or "Unknown" in line]
    assert not failures, failures
    return driver


def planned_steps(layer):
    """The plan's moves (laser off) and cuts (laser on), µm, as the decoder should see them."""
    steps = []
    for path in layer["paths_mm"]:
        steps.append((path[0], 0))
        steps.extend((point, 1) for point in path[1:])
    return steps


def payload(program):
    return b"".join(decode_bytes(bytes.fromhex(p)[2:], magic=0x88) for p in program["packets"])


PROGRAMS = ["square", "gauge", "scattered", "negative"]


def program_named(streams, name):
    return next(p for p in streams["programs"] if p["name"] == name)


def test_every_program_is_a_stream_the_test_knows(streams):
    assert streams["magic"] == 0x88
    assert [p["name"] for p in streams["programs"]] == PROGRAMS


@pytest.mark.parametrize("name", PROGRAMS)
def test_meerk40t_reads_back_the_plans_moves_speeds_and_powers(streams, name):
    program = program_named(streams, name)
    driver = run_program(program)
    assert len(driver.plots) == len(program["layers"])
    for layer, plot in zip(program["layers"], driver.plots):
        assert plot["speed"] == pytest.approx(layer["speed_mm_per_s"], abs=0.001)
        assert abs(plot["min_power"] - layer["min_power_percent"]) <= POWER_STEP
        assert abs(plot["max_power"] - layer["max_power_percent"]) <= POWER_STEP
        planned = planned_steps(layer)
        assert len(plot["steps"]) == len(planned)
        for (x_um, y_um, on), ((x_mm, y_mm), laser) in zip(plot["steps"], planned):
            assert on == laser, "a travel with the laser on, or a cut with it off"
            assert abs(x_um - x_mm * 1000) <= 0.5 + 1e-6
            assert abs(y_um - y_mm * 1000) <= 0.5 + 1e-6


@pytest.mark.parametrize("name", PROGRAMS)
def test_no_travel_fires_the_laser_and_the_file_ends(streams, name):
    program = program_named(streams, name)
    driver = run_program(program)
    path_starts = sum(len(layer["paths_mm"]) for layer in program["layers"])
    steps = [s for plot in driver.plots for s in plot["steps"]]
    travels = [s for s in steps if s[2] == 0]
    assert len(travels) == path_starts
    assert driver.ended == 1
    commands = list(parse_commands(payload(program)))
    assert commands[-1] == b"\xd7"
    # Every move is absolute: no relative move or cut (89-8B, A9-AB), no 80 00 / A0 00, and no
    # command the two decoders read differently.
    assert {c[0] for c in commands} <= {0xE6, 0xCA, 0xC9, 0xC6, 0x88, 0xA8, 0xE5, 0xD7}
    # Nor CA 01 00, "end layer" to MeerK40t but "overscan off" to ruida-pa.
    assert not [c for c in commands if c[:2] == b"\xca\x01"]


@pytest.mark.parametrize("name", PROGRAMS)
def test_packets_split_only_between_commands_and_the_file_sum_is_meerk40ts(streams, name):
    program = program_named(streams, name)
    whole = list(parse_commands(payload(program)))
    by_packet = []
    for packet in program["packets"]:
        by_packet.extend(parse_commands(decode_bytes(bytes.fromhex(packet)[2:], magic=0x88)))
    assert by_packet == whole
    job = RDJob()
    job.buffer = whole[:-2]
    sum_command = whole[-2]
    assert sum_command[:2] == b"\xe5\x05"
    assert decodeu35(sum_command[2:7]) == job.file_sum() + 0xD7


def test_the_gauge_lands_where_it_was_asked(streams):
    program = program_named(streams, "gauge")
    driver = run_program(program)
    asked = program["center_mm"]
    holes = driver.plots[0]["steps"]
    centres = []
    for hole in (holes[:49], holes[49:]):
        # A closed 48-gon: its vertices (the closing one left out) average to its centre.
        ring = hole[1:]
        assert len(ring) == 48
        centres.append([sum(p[i] for p in ring) / 48 / 1000 for i in (0, 1)])
    centre = [(centres[0][i] + centres[1][i]) / 2 for i in (0, 1)]
    assert centre == pytest.approx(asked, abs=0.001)


def direct(streams, kind):
    return [d for d in streams["direct"] if d["kind"] == kind]


def test_direct_moves_are_absolute_as_meerk40ts_own_driver_sends_them(streams):
    # MeerK40t's emulator ignores D9 10's option byte, so it is compared with what MeerK40t's
    # driver sends for an absolute move (its relative moves carry 02, "current" to ruida-pa).
    absolute = RDJob()._rapid_options(origin=True)
    for kind in ("move_xy", "move_z", "move_u"):
        (move,) = direct(streams, kind)
        payload = decode_bytes(bytes.fromhex(move["packet"])[2:], magic=0x88)
        assert payload[0] == 0xD9
        assert payload[2:3] == absolute, kind


def test_direct_moves_and_stop_are_read_as_sent(streams):
    emulator, driver, replies, log = controller()
    (xy,) = direct(streams, "move_xy")
    assert send(emulator, replies, xy["packet"]) == ACK
    assert [tuple(float(v.removesuffix("mm")) for v in m) for m in driver.moves] == [
        (xy["x_um"] / 1000, xy["y_um"] / 1000)
    ]
    for kind, axis in (("move_z", "z"), ("move_u", "u")):
        (move,) = direct(streams, kind)
        assert send(emulator, replies, move["packet"]) == ACK
        name, value = driver.axes[-1]
        assert name == axis
        assert value == pytest.approx(move[f"{axis}_um"], abs=0.5)
    (stop,) = direct(streams, "stop")
    assert send(emulator, replies, stop["packet"]) == ACK
    assert driver.resets == 1
    (alive,) = direct(streams, "keep_alive")
    assert send(emulator, replies, alive["packet"]) == ACK


def test_a_corrupted_packet_is_naked(streams):
    emulator, _, replies, _ = controller()
    packet = bytearray(bytes.fromhex(program_named(streams, "square")["packets"][0]))
    packet[5] ^= 0x01
    assert send(emulator, replies, packet.hex()) == NAK


def parse_answer(register, datagram):
    out = subprocess.run(
        encoder() + ["parse-answer", register, datagram.hex()],
        check=True,
        capture_output=True,
        text=True,
    )
    return out.stdout.strip()


@pytest.mark.parametrize("position_um", [(123456, 7890), (-2500, 0)])
def test_register_reads_are_answered_and_the_answers_read_back(streams, position_um):
    emulator, driver, replies, log = controller()
    driver.position_um = position_um
    read = {d["register"]: d["packet"] for d in direct(streams, "read")}
    for register, expected in (
        ("position_x", position_um[0] / 1000),
        ("position_y", position_um[1] / 1000),
        # MeerK40t's emulated bed: 320 x 220 mm.
        ("bed_size_x", 320.0),
        ("bed_size_y", 220.0),
    ):
        before = len(replies)
        assert send(emulator, replies, read[register]) == ACK
        answer = replies[before + 1]
        mem, value, _ = RDJob().decode_reply(emulator.unswizzle(answer))
        assert mem is not None, f"MeerK40t does not know the register {register} was read"
        assert float(parse_answer(register, answer)) == pytest.approx(expected, abs=0.001)
        assert value / 1000 == pytest.approx(expected, abs=0.001)
    before = len(replies)
    assert send(emulator, replies, read["machine_status"]) == ACK
    # The emulator's idle status is 22 (it says 21 running, 23 paused).
    assert parse_answer("machine_status", replies[before + 1]) == "22"


RUIDA_PA = os.environ.get("KERFMETER_RUIDA_PA")
# What ruida-pa flags: an error, a fatal error, a warning, a critical error.
RPA_FLAGS = (":ERR:", ":FTL:", ":WRN:", ":CRT:")
RPA_XY = re.compile(r"^(MOVE|CUT)_FAR_XY X=(-?[0-9.]+)mm Y=(-?[0-9.]+)mm$")
RPA_SPEED = re.compile(r"^SPEED_LASER_1 Speed:([0-9.]+)mm/S$")
RPA_POWER = re.compile(r"^(MIN|MAX)_POWER_1 Power:([0-9.]+)%$")


def rpa_decode(tmp_path, name, swizzled):
    """ruida-pa's decoded messages for the swizzled stream, and its flagged lines."""
    if not RUIDA_PA:
        pytest.skip("KERFMETER_RUIDA_PA is set by cargo xtask test-python")
    rd = tmp_path / f"{name}.rd"
    rd.write_bytes(swizzled)
    out = tmp_path / f"{name}.txt"
    subprocess.run(
        [RUIDA_PA, "--magic", "0x88", "-q", "-o", str(out), str(rd)],
        check=True,
        timeout=600,
        stdout=subprocess.DEVNULL,
    )
    lines = out.read_text().splitlines()
    flagged = [line for line in lines if any(flag in line for flag in RPA_FLAGS)]
    # Each decoded command is the line after its header (`...:T=0002 R=0084 SUM=...:`).
    messages = [lines[i + 1] for i, line in enumerate(lines[:-1]) if re.search(r":T=\d+ R=\d+ SUM=", line)]
    return messages, flagged, lines


@pytest.mark.parametrize("name", PROGRAMS)
def test_ruida_pa_reads_the_same_program(streams, name, tmp_path):
    program = program_named(streams, name)
    swizzled = b"".join(bytes.fromhex(p)[2:] for p in program["packets"])
    messages, flagged, lines = rpa_decode(tmp_path, name, swizzled)
    assert not flagged, flagged
    names = {m.split()[0] for m in messages}
    assert names <= {"SET_ABSOLUTE", "SELECT_LAYER", "SPEED_LASER_1", "MIN_POWER_1",
                     "MAX_POWER_1", "MOVE_FAR_XY", "CUT_FAR_XY", "END_JOB", "EOF"}, names
    assert messages[-1] == "EOF"
    assert any("Checksum OK" in line for line in lines)
    steps = [RPA_XY.match(m).groups() for m in messages if RPA_XY.match(m)]
    planned = [step for layer in program["layers"] for step in planned_steps(layer)]
    assert len(steps) == len(planned)
    for (kind, x, y), ((x_mm, y_mm), laser) in zip(steps, planned):
        assert kind == ("CUT" if laser else "MOVE")
        assert abs(float(x) - x_mm) <= 0.0005 + 1e-9
        assert abs(float(y) - y_mm) <= 0.0005 + 1e-9
    speeds = [float(RPA_SPEED.match(m).group(1)) for m in messages if RPA_SPEED.match(m)]
    assert speeds == [layer["speed_mm_per_s"] for layer in program["layers"]]
    powers = [RPA_POWER.match(m).groups() for m in messages if RPA_POWER.match(m)]
    expected = [(which, layer[f"{which.lower()}_power_percent"]) for layer in program["layers"]
                for which in ("MIN", "MAX")]
    assert len(powers) == len(expected)
    for (which, value), (want_which, want) in zip(powers, expected):
        # ruida-pa prints one decimal.
        assert which == want_which and abs(float(value) - want) <= 0.05 + POWER_STEP


def test_ruida_pa_reads_the_direct_moves_as_absolute(streams, tmp_path):
    moves = [d for d in streams["direct"] if d["kind"] in ("move_xy", "move_z", "move_u")]
    swizzled = b"".join(bytes.fromhex(d["packet"])[2:] for d in moves)
    messages, flagged, _ = rpa_decode(tmp_path, "direct", swizzled)
    assert not flagged, flagged
    xy, z, u = moves
    assert messages == [
        f"JOG_XY MACHINE X={xy['x_um'] / 1000:.3f}mm Y={xy['y_um'] / 1000:.3f}mm",
        f"JOG_Z MACHINE Z={z['z_um'] / 1000:.3f}mm",
        f"JOG_U MACHINE U={u['u_um'] / 1000:.3f}mm",
    ]
