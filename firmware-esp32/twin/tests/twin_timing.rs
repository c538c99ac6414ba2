//! The twin's timing against the real firmware: jittered and late ticks, link work per frame,
//! another host's bursts, flash operations that stall the core, and the watchdog that resets it
//! mid-erase.

mod common;
use common::measure;

use kerfmeter_firmware::build::FLASH_WATCHDOG_TIMEOUT_MS;
use kerfmeter_firmware::controller::{MAX_GAP_PERIODS, PERIOD_US};
use kerfmeter_firmware::link::FRAMES_PER_TICK;
use kerfmeter_protocol::{
    Deframer, DeviceConfig, Envelope, Fault, Feed, MAX_REQUEST_FRAME_LEN, MAX_RESPONSE_FRAME_LEN,
    Request, Response, RunParams, RunState, encode_frame,
};
use kerfmeter_twin::sim::MAX_LEAD_MS;
use kerfmeter_twin::{Twin, TwinOptions};

/// A twin with the plant parameters `set` (`NAME=VALUE`), a few ticks after boot.
fn twin(set: &[&str]) -> Twin {
    let mut options = TwinOptions {
        kerf_um: 150.0,
        seed: 11,
        ..TwinOptions::default()
    };
    for assignment in set {
        options.plant.assign(assignment).unwrap();
    }
    let mut t = Twin::new(options);
    t.advance_ticks(5);
    t
}

/// The times of the next `n` ticks.
fn tick_times(t: &mut Twin, n: usize) -> Vec<u64> {
    (0..n)
        .map(|_| {
            let at = t.next_tick_us();
            t.tick();
            at
        })
        .collect()
}

/// A configuration told apart by `n`.
fn config(n: u32) -> DeviceConfig {
    DeviceConfig {
        encoder_zero_raw: (n % 10_000) as u16 + 1,
        ..DeviceConfig::DEFAULT
    }
}

/// What saving configurations one after the other (two ticks apart) came to, at the first
/// save that erased a flash sector.
struct EraseSave {
    /// The last configuration saved and answered before it.
    stored: DeviceConfig,
    /// The configuration it was saving.
    saving: DeviceConfig,
    /// Its answer (none: the watchdog reset the device).
    answer: Option<Response>,
    started_us: u64,
    ended_us: u64,
}

/// Save configurations until one erases a sector (the store fills its pages first).
fn save_until_an_erase(t: &mut Twin) -> EraseSave {
    let mut stored = DeviceConfig::DEFAULT;
    for n in 0..1000 {
        let saving = config(n);
        let (started_us, erases) = (t.now_us(), t.flash().erases());
        let answer = t.try_request(&Request::SetConfig(saving));
        if t.flash().erases() > erases || answer.is_none() {
            return EraseSave {
                stored,
                saving,
                answer,
                started_us,
                ended_us: t.now_us(),
            };
        }
        assert!(matches!(answer, Some(Response::Config(_))), "{answer:?}");
        stored = saving;
        t.advance_ticks(2);
    }
    panic!("1000 saves and no erase");
}

fn stored_config(t: &mut Twin) -> (DeviceConfig, bool) {
    match t.request(&Request::GetConfig) {
        Response::Config(report) => (report.config, report.defaults_in_use),
        other => panic!("{other:?}"),
    }
}

#[test]
fn ticks_arrive_with_the_configured_jitter() {
    let mut t = twin(&[
        "tick_jitter_us=60",
        "late_ticks_per_s=0",
        "host_burst_frames=0",
    ]);
    let times = tick_times(&mut t, 5000);
    // Ticks are due on the period's grid from boot.
    let first_due = (times[0] + PERIOD_US / 2) / PERIOD_US * PERIOD_US;
    let offsets: Vec<f64> = (0..times.len())
        .map(|i| times[i] as f64 - (first_due + i as u64 * PERIOD_US) as f64)
        .collect();
    let n = offsets.len() as f64;
    let mean = offsets.iter().sum::<f64>() / n;
    let sd = (offsets.iter().map(|o| (o - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(mean.abs() < 5.0, "mean {mean:.1} µs");
    assert!((sd - 60.0).abs() < 4.0, "SD {sd:.1} µs");
    assert!(times.windows(2).all(|w| w[1] > w[0]));
    assert_eq!(
        t.now_us(),
        *times.last().unwrap(),
        "the core sits at the last tick"
    );
}

/// A twin with plant parameters set directly, beyond their ranges where need be (`assign`
/// checks the range).
fn twin_with(set: impl FnOnce(&mut TwinOptions)) -> Twin {
    let mut options = TwinOptions {
        kerf_um: 150.0,
        seed: 11,
        ..TwinOptions::default()
    };
    set(&mut options);
    let mut t = Twin::new(options);
    t.advance_ticks(5);
    t
}

/// A reset to zero, polling every 10 ms; its end state.
fn reset(t: &mut Twin) -> RunState {
    assert_eq!(t.request(&Request::Reset), Response::Ok);
    for _ in 0..1000 {
        t.advance_ticks(10);
        let Response::Status(s) = t.request(&Request::GetStatus) else {
            panic!("no status");
        };
        if s.state != RunState::Resetting {
            return s.state;
        }
    }
    panic!("the reset did not end in 10 s");
}

#[test]
fn late_ticks_at_the_twins_upper_range_are_ridden_through() {
    // 5 ms late (6 ms between two steps, twice the old 3-period limit), 5 a second, with the
    // largest jitter: the reset and the run end as without them, to within the noise.
    let upper = ["late_ticks_per_s=5", "late_tick_ms=5", "tick_jitter_us=200"];
    let mut t = twin(&upper);
    let unlate = measure(
        &mut twin(&["late_ticks_per_s=0", "tick_jitter_us=200"]),
        &RunParams::DEFAULT,
    )
    .unwrap();
    assert_eq!(reset(&mut t), RunState::Idle);
    let late = measure(&mut t, &RunParams::DEFAULT).unwrap();
    assert!(
        (late.kerf_um - unlate.kerf_um).abs() < 3.0,
        "{} µm vs {} µm on time",
        late.kerf_um,
        unlate.kerf_um
    );
    let Response::Status(status) = t.request(&Request::GetStatus) else {
        panic!("no status");
    };
    assert!(status.longest_gap_us > 5_000, "late ticks came: {status:?}");
}

#[test]
fn a_tick_later_than_the_firmware_rides_through_faults_a_run_with_the_motor_safe() {
    // 8 ms late (beyond the twin's range: a stalled loop): over the 8-period limit.
    let mut t = twin_with(|o| {
        o.plant.late_ticks_per_s = 5.0;
        o.plant.late_tick_ms = MAX_GAP_PERIODS as f64;
    });
    assert_eq!(
        measure(&mut t, &RunParams::DEFAULT),
        Err(Fault::StepOverrun)
    );
    assert!(t.motor_safe());
}

#[test]
fn frequent_late_ticks_fault_a_run_with_the_motor_safe() {
    // 4 ms late, 50 a second (beyond the twin's range: a loop late a fifth of the time). Each
    // one alone would be ridden through.
    let mut t = twin_with(|o| {
        o.plant.late_ticks_per_s = 50.0;
        o.plant.late_tick_ms = 4.0;
    });
    assert_eq!(
        measure(&mut t, &RunParams::DEFAULT),
        Err(Fault::StepOverrun)
    );
    assert!(t.motor_safe());
}

#[test]
fn frames_cost_core_time_and_a_burst_is_spread_over_passes() {
    let quiet = ["tick_jitter_us=0", "late_ticks_per_s=0"];
    // The client's own frames: each one costs its link work.
    let mut t = twin(&[
        quiet[0],
        quiet[1],
        "host_burst_frames=0",
        "frame_cost_us=80",
    ]);
    let before = t.now_us();
    t.request(&Request::GetStatus);
    assert_eq!(t.now_us() - before, 80);

    // A host polling after every tick, with a burst of 10 more frames every 200 ms, 150 µs
    // each (1.5 ms of link work): the link takes two frames a pass, so no tick moves; the burst
    // is spread over the passes at 200..204 ms, and the poll sent with it (queued behind it) is
    // answered in the pass at 205 ms.
    let heavy = [
        quiet[0],
        quiet[1],
        "host_burst_frames=10",
        "frame_cost_us=150",
    ];
    let mut t = twin(&heavy);
    let mut late_answers = Vec::new();
    for _ in 0..300 {
        let at = t.next_tick_us();
        assert_eq!(at % PERIOD_US, 0, "a tick moved");
        t.tick();
        t.request(&Request::GetStatus);
        if t.now_us() - at > 2 * 150 {
            late_answers.push((at, t.now_us()));
        }
    }
    assert_eq!(late_answers, [(200_000, 205_000 + 150)]);
}

#[test]
fn frames_sent_at_once_are_answered_in_order_a_few_a_pass() {
    let mut t = twin(&[
        "tick_jitter_us=0",
        "late_ticks_per_s=0",
        "host_burst_frames=0",
    ]);
    let mut bytes = Vec::new();
    let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
    for seq in 1..=7 {
        let request = Envelope {
            seq,
            body: Request::GetStatus,
        };
        bytes.extend_from_slice(encode_frame(&request, &mut buf).unwrap());
    }
    let first_tick_us = t.now_us();
    let mut wire = Vec::new();
    t.receive(&bytes, |frame| wire.extend_from_slice(frame));
    let mut deframer = Deframer::<MAX_RESPONSE_FRAME_LEN>::new();
    let mut input = &wire[..];
    let mut seqs = Vec::new();
    while let Feed::Frame { result, rest } = deframer.feed::<Envelope<Response>>(input) {
        seqs.push(result.unwrap().seq);
        input = rest;
    }
    assert_eq!(seqs, [1, 2, 3, 4, 5, 6, 7]);
    // Seven frames, two a pass: the last one is answered in the fourth pass from here.
    assert_eq!(FRAMES_PER_TICK, 2);
    assert_eq!(t.now_us() / PERIOD_US, first_tick_us / PERIOD_US + 3);
}

#[test]
fn a_burst_of_host_frames_does_not_fault_a_run() {
    let mut t = twin(&[
        "host_burst_frames=30",
        "frame_cost_us=100",
        "host_burst_period_ms=100",
    ]);
    measure(&mut t, &RunParams::DEFAULT).unwrap();
}

#[test]
fn a_flash_erase_stalls_the_core_and_the_status_is_answered_late() {
    let mut t = twin(&[]);
    let save = save_until_an_erase(&mut t);
    assert!(
        matches!(save.answer, Some(Response::Config(_))),
        "a 400 ms erase fits the flash operation's watchdog window: {:?}",
        save.answer
    );
    let stall_us = save.ended_us - save.started_us;
    assert!(
        (400_000..FLASH_WATCHDOG_TIMEOUT_MS * 1000).contains(&stall_us),
        "stalled {stall_us} µs"
    );
    // The poll that follows is answered after the stall; no tick ran meanwhile, and the next
    // one comes a period after the stall (the board's ticker restarts).
    assert!(matches!(
        t.request(&Request::GetStatus),
        Response::Status(_)
    ));
    assert!(t.now_us() >= save.started_us + 400_000);
    assert!(t.next_tick_us() >= save.ended_us + PERIOD_US - 200);
    // The lock-step lead counts from the answer, not from before the stall.
    assert!(t.lead_ticks() >= 98, "{}", t.lead_ticks());
    assert_eq!(stored_config(&mut t), (save.saving, false));
    assert_eq!(t.reboots(), 0);
}

#[test]
fn the_plant_keeps_moving_through_a_flash_stall() {
    // Slow page writes: a save stalls the core for tens of ms.
    let mut t = twin(&["flash_write_ms=10"]);
    assert_eq!(t.request(&Request::Run(RunParams::DEFAULT)), Response::Ok);
    t.advance_ticks(150);
    assert!(t.plant().hub_deg_per_s().abs() > 1.0, "the hub turns");
    // Abort and save in the same pass of link work, before a tick puts the bridge safe: the
    // device puts it safe itself before writing flash.
    assert_eq!(t.request(&Request::Abort), Response::Ok);
    let (hub_deg, started_us) = (t.plant().hub_deg(), t.now_us());
    assert!(matches!(
        t.request(&Request::SetConfig(config(1))),
        Response::Config(_)
    ));
    let stall_us = t.now_us() - started_us;
    assert!(stall_us >= 10_000, "stalled {stall_us} µs");
    // The plant ran through the stall: the hub coasted on from about 80 °/s (a few tenths of a
    // degree), and came to rest, since nothing drove it.
    let moved_deg = t.plant().hub_deg() - hub_deg;
    assert!(
        moved_deg.abs() > 0.1,
        "the hub moved {moved_deg}° during the stall"
    );
    assert_eq!(t.plant().hub_deg_per_s(), 0.0, "at rest after the stall");
    assert!(
        t.next_tick_us() > t.now_us(),
        "no tick ran during the stall"
    );
}

#[test]
fn a_save_right_after_abort_does_not_drive_the_motor_through_the_stall() {
    let mut t = twin(&[]);
    assert_eq!(t.request(&Request::Run(RunParams::DEFAULT)), Response::Ok);
    t.advance_ticks(150);
    assert_eq!(t.request(&Request::Abort), Response::Ok);
    t.request(&Request::SetConfig(config(1)));
    assert!(t.motor_safe(), "driven through the save's stall");
}

#[test]
fn a_watchdog_reset_mid_erase_keeps_the_stored_calibration() {
    // An erase longer than even the flash operation's watchdog window (a failing part, beyond
    // the parameter's range): the device resets in the middle of it, the sector torn.
    let mut options = TwinOptions {
        kerf_um: 150.0,
        seed: 11,
        ..TwinOptions::default()
    };
    options.plant.flash_erase_ms = 1.25 * FLASH_WATCHDOG_TIMEOUT_MS as f64;
    let mut t = Twin::new(options);
    t.advance_ticks(5);
    let boot_id = |t: &mut Twin| match t.request(&Request::GetInfo) {
        Response::Info(info) => info.boot_id,
        other => panic!("{other:?}"),
    };
    let first_boot = boot_id(&mut t);
    let save = save_until_an_erase(&mut t);
    assert_eq!(save.answer, None, "no answer: the device reset");
    assert_eq!(t.reboots(), 1);
    assert_ne!(boot_id(&mut t), first_boot);
    // Reset at the end of the erase's window, which the firmware opened just before it: after
    // the request's link work and the save's page writes before the erase (3 ms each, about 20
    // on this flash: the store moves its live items on before it erases).
    let stall_us = save.ended_us - save.started_us;
    let window_us = FLASH_WATCHDOG_TIMEOUT_MS * 1000;
    assert!(
        (window_us..=window_us + 100_000).contains(&stall_us),
        "reset after {stall_us} µs"
    );
    t.advance_ticks(5);
    // "Never lose a stored calibration": the last configuration saved is still in use.
    assert_eq!(stored_config(&mut t), (save.stored, false));
    // And the flash works again: a new save (its repair done at boot) persists.
    assert!(matches!(
        t.request(&Request::SetConfig(save.saving)),
        Response::Config(_)
    ));
    t.reboot();
    assert_eq!(stored_config(&mut t), (save.saving, false));
}

#[test]
fn a_save_on_a_slow_flash_is_answered_without_a_reset() {
    // The slowest erase of the parameter's range.
    let mut t = twin(&["flash_erase_ms=1000"]);
    let save = save_until_an_erase(&mut t);
    assert!(
        matches!(save.answer, Some(Response::Config(_))),
        "{:?}",
        save.answer
    );
    assert_eq!(t.reboots(), 0);
}

#[test]
fn in_lock_step_the_twin_leads_the_host_by_the_set_time_whatever_the_tick_times() {
    // Large jitter and frequent late ticks: the serve loop runs batches of lead ticks, each
    // counted again after the last, until the next tick would start past the lead.
    let mut t = twin(&["tick_jitter_us=200", "late_ticks_per_s=5", "late_tick_ms=2"]);
    for _ in 0..20 {
        t.request(&Request::GetStatus);
        let limit_us = t.now_us() + MAX_LEAD_MS * 1000;
        let mut ran = 0;
        loop {
            let lead = t.lead_ticks().min(50);
            if lead == 0 {
                break;
            }
            t.advance_ticks(lead);
            ran += lead;
        }
        assert!((95..=101).contains(&ran), "{ran} ticks");
        assert!(t.next_tick_us() >= limit_us);
        // The last tick started within a tick's spread of the limit.
        assert!(
            t.now_us() < limit_us + 2 * 1000,
            "{} vs {limit_us}",
            t.now_us()
        );
    }
}

#[test]
fn the_step_of_a_stalled_pass_runs_before_the_host_hears_back() {
    // A save stalls the core for its flash writes, longer than any gap the firmware rides
    // through.
    // On the board the answer leaves only after that pass's step, so a run the host starts on
    // hearing back does not see the stall as an overrun of its own steps.
    let mut t = twin(&["flash_write_ms=10"]);
    let before = t.now_us();
    assert!(matches!(
        t.request(&Request::SetConfig(config(1))),
        Response::Config(_)
    ));
    assert!(
        t.now_us() - before > MAX_GAP_PERIODS * PERIOD_US,
        "the save stalled the core"
    );
    assert_eq!(t.request(&Request::Reset), Response::Ok);
    t.advance_ticks(1500);
    let status = match t.request(&Request::GetStatus) {
        Response::Status(s) => s,
        other => panic!("{other:?}"),
    };
    assert_eq!(status.state, RunState::Idle, "{status:?}");
    measure(&mut t, &RunParams::DEFAULT).unwrap();
}
