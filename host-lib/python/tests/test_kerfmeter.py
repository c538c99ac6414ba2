"""The Python package against the digital twin: the three calls, a fault, the GIL, Ctrl-C
mid-run, repeated measurements, and the plan functions (dilate, gauge)."""

import _thread
import io
import threading
import time

import pytest

import kerfmeter


@pytest.fixture
def meter():
    with kerfmeter.Kerfmeter.sim(kerf_um=200) as m:
        yield m


def test_the_three_calls(meter):
    meter.reset_kerfmeter()
    assert meter.get_kerf_value() is None
    seen = []
    result = meter.run_kerfmeter(thickness_mm=4, progress=lambda *p: seen.append(p))
    assert isinstance(result, kerfmeter.KerfResult)
    assert result.kerf_um == pytest.approx(200, abs=15)
    assert meter.get_kerf_value() == result
    assert result.flags == []
    assert 40 < result.force_at_jam_n < 70
    states = {state for state, _, _ in seen}
    assert "Ramping" in states, states
    meter.reset_kerfmeter()
    assert meter.get_kerf_value() is None


def test_info_and_status_are_dicts(meter):
    assert meter.status()["state"] == "Idle"
    assert "boot_id" in meter.info()


def test_a_fault_names_itself_with_the_librarys_message():
    with kerfmeter.Kerfmeter.sim(fault="no-inset") as m:
        with pytest.raises(kerfmeter.DeviceFaultError) as caught:
            m.run_kerfmeter()
        assert caught.value.fault == "Overtravel"
        assert "the device stopped" in str(caught.value)
        assert isinstance(caught.value, kerfmeter.KerfmeterError)
        assert m.status()["state"] == {"Fault": "Overtravel"}
        m.reset_kerfmeter()  # clears the latched fault
        assert m.status()["state"] == "Idle"


def test_bad_arguments_are_refused_before_anything_moves(meter):
    with pytest.raises(kerfmeter.BadArgumentError, match="thickness"):
        meter.run_kerfmeter(thickness_mm=-1)
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.Kerfmeter.sim(fault="no-such-fault")
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.Kerfmeter.sim(no_such_plant_parameter=1.0)
    with pytest.raises(kerfmeter.BadArgumentError):
        meter.measure(0)


def test_a_closed_meter_says_so():
    m = kerfmeter.Kerfmeter.sim()
    m.close()
    with pytest.raises(kerfmeter.CommunicationError, match="closed"):
        m.status()
    with pytest.raises(kerfmeter.CommunicationError):
        kerfmeter.Kerfmeter.open("/dev/no-such-kerfmeter")


def test_the_gil_is_released_while_the_device_works(meter):
    done = threading.Event()
    ticks = 0

    def work():
        try:
            meter.run_kerfmeter()
        finally:
            done.set()

    worker = threading.Thread(target=work)
    worker.start()
    while not done.is_set():
        ticks += 1
    worker.join()
    # Held through the run, the GIL would let this loop turn only at the poll boundaries.
    assert ticks > 100_000, ticks


def test_ctrl_c_mid_run_aborts_and_leaves_the_motor_safe(meter):
    seen = io.StringIO()

    def progress(state, torque_nm, angle_deg):
        print(state, torque_nm, angle_deg, file=seen)

    def press_ctrl_c_while_ramping():
        for _ in range(3000):
            if "Ramping" in seen.getvalue():
                _thread.interrupt_main()
                return
            time.sleep(0.001)

    presser = threading.Thread(target=press_ctrl_c_while_ramping)
    presser.start()
    with pytest.raises(KeyboardInterrupt):
        meter.run_kerfmeter(progress=progress)
    presser.join()
    status = meter.status()
    assert status["state"] == "Idle", status
    assert meter.get_kerf_value() is None
    # The device is usable again at once.
    assert meter.run_kerfmeter().kerf_um == pytest.approx(200, abs=15)


def test_an_exception_in_progress_stops_the_run(meter):
    def progress(state, torque_nm, angle_deg):
        if state == "Ramping":
            raise RuntimeError("stop button")

    with pytest.raises(RuntimeError, match="stop button"):
        meter.run_kerfmeter(progress=progress)
    assert meter.status()["state"] == "Idle"


def test_measure_summarises_repeated_runs():
    with kerfmeter.Kerfmeter.sim(kerf_um=150, kerf_sd_um=5, seed=3) as m:
        placed = []
        result = m.measure(3, before_gauge=placed.append)
    assert placed == [0, 1, 2]
    assert result.n == 3 and len(result.runs) == 3
    kerfs = [r.kerf_um for r in result.runs]
    assert result.mean_um == pytest.approx(sum(kerfs) / 3)
    assert result.sd_um > 0
    assert result.ci95_um is not None and result.ci95_um > 0
    assert result.min_um == min(kerfs) and result.max_um == max(kerfs)


PLAN = """<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50">
  <rect id="part" x="10" y="10" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
</svg>"""


def test_dilate_writes_the_plan_and_reports_like_the_cli(tmp_path):
    plan = tmp_path / "plan.svg"
    plan.write_text(PLAN)
    out = tmp_path / "plan-k200.svg"
    report = kerfmeter.dilate(plan, out, 200)
    assert report["contours_dilated"] == 1
    assert report["kerf_um"] == 200
    assert report["output"] == str(out)
    assert report["format"] == "svg"
    assert '<path id="part"' in out.read_text()
    assert plan.read_text() == PLAN

    dry = kerfmeter.dilate(plan, None, 200, dry_run=True)
    assert dry["dry_run"] is True and dry["output"] is None


def test_dilate_refuses_what_would_lose_work(tmp_path):
    plan = tmp_path / "plan.svg"
    plan.write_text(PLAN)
    with pytest.raises(kerfmeter.PlanError):
        kerfmeter.dilate(plan, plan, 200)
    assert plan.read_text() == PLAN
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.dilate(plan, tmp_path / "out.svg", -5)
    with pytest.raises(kerfmeter.PlanError):
        kerfmeter.dilate(tmp_path / "missing.svg", tmp_path / "out.svg", 200)
    bad = tmp_path / "bad.svg"
    bad.write_text("<svg")
    with pytest.raises(kerfmeter.PlanError):
        kerfmeter.dilate(bad, tmp_path / "out.svg", 200)
    assert not (tmp_path / "out.svg").exists()


def test_gauge_draws_the_spiral(tmp_path):
    out = tmp_path / "gauge.svg"
    report = kerfmeter.gauge(out, label=True, test_piece_kerf_um=150)
    assert report["output"] == str(out)
    assert report["pitch_um_per_deg"] == 2.774
    assert report["test_piece"]["kerf_um"] == 150
    assert out.read_text().startswith("<")
    dxf = kerfmeter.gauge(tmp_path / "gauge.dxf", jam_direction="ccw")
    assert dxf["format"] == "dxf" and dxf["jam_direction"] == "ccw"
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.gauge(tmp_path / "g.svg", jam_direction="up")


def test_ctrl_c_is_seen_without_a_progress_callback():
    # No Python code runs during this run: only the binding's own signal check can see Ctrl-C.
    # In real time a run lasts seconds; the interrupt comes well inside it.
    with kerfmeter.Kerfmeter.sim(kerf_um=200, realtime=True) as m:
        presser = threading.Timer(0.5, _thread.interrupt_main)
        presser.start()
        with pytest.raises(KeyboardInterrupt):
            m.run_kerfmeter()
        presser.join()
        assert m.status()["state"] == "Idle"
        assert m.get_kerf_value() is None
