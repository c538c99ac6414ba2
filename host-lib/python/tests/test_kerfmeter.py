"""The Python package against the digital twin: the three calls, a fault, the GIL, Ctrl-C
mid-run, repeated measurements, and the plan functions (dilate, gauge)."""

import _thread
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


def test_the_package_says_its_version():
    assert kerfmeter.__version__.count(".") == 2, kerfmeter.__version__


def test_info_and_status_are_dicts(meter):
    assert meter.status()["state"] == "Idle"
    assert "boot_id" in meter.info()


def test_a_fault_names_itself_with_the_librarys_message():
    with kerfmeter.Kerfmeter.sim(fault="no-inset") as m:
        with pytest.raises(kerfmeter.DeviceFaultError) as caught:
            m.run_kerfmeter()
        assert caught.value.fault == "Overtravel"
        assert "the device stopped" in str(caught.value)
        # The library's advice, in Python's words: methods, not the command line's commands.
        assert "then `clear_fault()` and `reset_kerfmeter()`" in str(caught.value)
        assert "kerfmeter clear-fault" not in str(caught.value)
        assert isinstance(caught.value, kerfmeter.KerfmeterError)
        assert m.status()["state"] == {"Fault": "Overtravel"}
        m.reset_kerfmeter()  # clears the latched fault
        assert m.status()["state"] == "Idle"


def test_a_motor_shaft_encoder_is_confirmed_at_its_mark_before_a_run():
    with kerfmeter.Kerfmeter.sim(encoder_on_motor_shaft=True) as m:
        hub_turn_unknown = 1 << 5  # the protocol's Conditions bit
        assert m.status()["conditions"] == hub_turn_unknown
        with pytest.raises(kerfmeter.KerfmeterError, match="confirm_hub_at_zero"):
            m.run_kerfmeter()
        m.confirm_hub_at_zero()
        assert m.status()["conditions"] == 0
        assert m.run_kerfmeter().kerf_um == pytest.approx(150, abs=15)


def test_bad_arguments_are_refused_before_anything_moves(meter):
    with pytest.raises(kerfmeter.BadArgumentError, match="thickness"):
        meter.run_kerfmeter(thickness_mm=-1)
    # Also a ValueError, as Python's own functions raise for a bad value.
    with pytest.raises(ValueError, match="thickness") as caught:
        meter.run_kerfmeter(thickness_mm=-1)
    assert isinstance(caught.value, kerfmeter.KerfmeterError)
    assert kerfmeter.BadArgumentError.__module__ == "kerfmeter"
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.Kerfmeter.sim(fault="no-such-fault")
    with pytest.raises(kerfmeter.BadArgumentError):
        kerfmeter.Kerfmeter.sim(no_such_plant_parameter=1.0)
    with pytest.raises(kerfmeter.BadArgumentError):
        meter.measure(0)
    # A negative count is a bad argument too, not an OverflowError.
    with pytest.raises(kerfmeter.BadArgumentError, match="fingers must be between 1 and 100"):
        meter.run_kerfmeter(fingers=-1)
    with pytest.raises(kerfmeter.BadArgumentError, match="n=-2"):
        meter.measure(-2)
    # The force is named as the caller gives it.
    with pytest.raises(kerfmeter.BadArgumentError, match="force_n"):
        meter.run_kerfmeter(force_n=1e9)


def test_a_closed_meter_says_so():
    m = kerfmeter.Kerfmeter.sim()
    m.close()
    with pytest.raises(kerfmeter.CommunicationError, match="closed"):
        m.status()
    with pytest.raises(kerfmeter.CommunicationError):
        kerfmeter.Kerfmeter.open("/dev/no-such-kerfmeter")


def test_the_gil_is_released_while_the_device_works():
    # In real time a run lasts seconds. Held through the run, the GIL would stall this loop
    # for whole runs; released, it only waits its turn (5 ms switch interval) and for the
    # binding's brief checks at each 20 ms poll. The bound is generous for a busy machine.
    with kerfmeter.Kerfmeter.sim(kerf_um=200, realtime=True) as m:
        done = threading.Event()

        def work():
            try:
                m.run_kerfmeter()
            finally:
                done.set()

        worker = threading.Thread(target=work)
        started = time.monotonic()
        worker.start()
        longest_gap_s = 0.0
        last = time.monotonic()
        while not done.is_set():
            now = time.monotonic()
            longest_gap_s = max(longest_gap_s, now - last)
            last = now
        worker.join()
        assert time.monotonic() - started > 1.0  # the loop turned through a real run
        assert longest_gap_s < 0.5, longest_gap_s


def test_ctrl_c_mid_run_aborts_and_leaves_the_motor_safe(meter):
    seen = []

    def progress(state, torque_nm, angle_deg):
        seen.append(state)
        if state == "Ramping":
            # Ctrl-C pressed while the motor turns: the signal arrives here, in the callback.
            _thread.interrupt_main()

    with pytest.raises(KeyboardInterrupt):
        meter.run_kerfmeter(progress=progress)
    assert seen[-1] == "Ramping", seen
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
    # The summary is the library's, over the device's single-precision numbers.
    assert result.min_um == pytest.approx(min(kerfs), rel=1e-6)
    assert result.max_um == pytest.approx(max(kerfs), rel=1e-6)


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
    # A refused plan leaves an earlier output as it was (the new one goes to a temporary file).
    crossing = tmp_path / "crossing.svg"
    crossing.write_text(PLAN.replace(
        '<rect id="part" x="10" y="10" width="20" height="20"',
        '<path id="part" d="M10 10 L30 30 L30 10 L10 30 Z"'))
    kept = tmp_path / "kept.svg"
    kept.write_text("an earlier output")
    # A file kerfmeter did not write is not replaced, unless forced.
    with pytest.raises(kerfmeter.PlanError, match="force"):
        kerfmeter.dilate(plan, kept, 200)
    assert kept.read_text() == "an earlier output"
    with pytest.raises(kerfmeter.PlanError, match="cannot dilate this plan"):
        kerfmeter.dilate(crossing, kept, 200, force=True)
    assert kept.read_text() == "an earlier output"
    # Refused with strict=True for an open cut, which is found as the plan is written.
    hinge = tmp_path / "hinge.svg"
    hinge.write_text(PLAN.replace(
        "</svg>", '<path id="slit" d="M12 40 L28 40" fill="none" stroke="red" stroke-width="0.01"/></svg>'))
    with pytest.raises(kerfmeter.PlanError, match="open"):
        kerfmeter.dilate(hinge, kept, 200, strict=True, force=True)
    assert kept.read_text() == "an earlier output"
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["bad.svg", "crossing.svg", "hinge.svg", "kept.svg", "plan.svg"]


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
    # With no inset the prongs turn freely in real time to the firmware's travel limit (about
    # 2 s), so the interrupt, sent 0.3 s in, lands well inside the run; a missed one ends the
    # run in an Overtravel fault (DeviceFaultError), never in a result.
    with kerfmeter.Kerfmeter.sim(realtime=True, fault="no-inset") as m:
        presser = threading.Timer(0.3, _thread.interrupt_main)
        presser.start()
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            m.run_kerfmeter()
        presser.join()
        assert time.monotonic() - started < 5
        assert m.status()["state"] == "Idle"
        assert m.get_kerf_value() is None


def test_ctrl_c_during_the_reset_before_a_run_stops_it_before_the_run():
    with kerfmeter.Kerfmeter.sim(kerf_um=200) as m:
        m.run_kerfmeter()  # leaves the hub at the jam, far from zero
        states = []

        def progress(state, torque_nm, angle_deg):
            states.append(state)
            if state == "Resetting":
                _thread.interrupt_main()

        with pytest.raises(KeyboardInterrupt):
            m.run_kerfmeter(progress=progress)
        assert states == ["Resetting"], states
        assert m.status()["state"] == "Idle"
        assert m.get_kerf_value() is None


def test_calls_from_the_progress_callback_do_not_hang(meter):
    # repr() never waits for the device.
    reprs = []
    meter.run_kerfmeter(progress=lambda *p: reprs.append(repr(meter)))
    assert reprs and reprs[0].startswith("Kerfmeter(")
    # A call on the device from its own callback would wait for itself: refused, run stopped.
    with pytest.raises(kerfmeter.KerfmeterError, match="its own progress callback"):
        meter.run_kerfmeter(progress=lambda *p: meter.status())
    assert meter.status()["state"] == "Idle"
    # abort() from the callback stops the run.
    with pytest.raises(kerfmeter.DeviceError, match="abort"):
        meter.run_kerfmeter(progress=lambda *p: meter.abort())
    assert meter.status()["state"] == "Idle"
    assert meter.get_kerf_value() is None


def test_abort_from_another_thread_stops_a_run():
    with kerfmeter.Kerfmeter.sim(realtime=True, fault="no-inset") as m:
        ramping = threading.Event()

        def progress(state, torque_nm, angle_deg):
            if state == "Ramping":
                ramping.set()

        def stop_when_ramping():
            ramping.wait(10)
            m.abort()

        stopper = threading.Thread(target=stop_when_ramping)
        stopper.start()
        started = time.monotonic()
        with pytest.raises(kerfmeter.DeviceError, match="abort"):
            m.run_kerfmeter(progress=progress)
        stopper.join()
        assert time.monotonic() - started < 5
        assert m.status()["state"] == "Idle"
        m.abort()  # idle: sent to the device at once
