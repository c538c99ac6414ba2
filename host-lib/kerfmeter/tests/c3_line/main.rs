//! The host's serial line as a real ESP32-C3 sees it (issue 32 §2): the client's real open
//! ([`Kerfmeter::from_port`], which every way of opening the device goes through), close and
//! re-open after a vanished port, run through a double of the chip's USB-Serial-JTAG port that
//! applies Espressif's documented line-state rules and reboots the twin behind it when they say
//! so ([`double`]).
//!
//! The figures (boot ids over a hundred commands, requests the chip received) are printed with
//! `cargo test -p kerfmeter --test c3_line -- --nocapture`.

mod double;

use std::collections::BTreeSet;
use std::time::Duration;

use double::{Action, C3, Driver, LineRequest, Pair, Source};
use kerfmeter::protocol::{Conditions, ErrorCode, GaugeGeometry, KerfResult, RunParams};
use kerfmeter::{Error, JointSpec, Kerfmeter, Options};
use kerfmeter_twin::TwinOptions;
use serialport::SerialPort;

/// Commands in the soak, as issue 32 asks.
const COMMANDS: usize = 100;

/// One write of one line, as serialport makes it.
#[derive(Debug, Clone, Copy)]
enum Step {
    Dtr(bool),
    Rts(bool),
}

/// What `Kerfmeter::open_with` wrote after the OS opened the port, before this fix.
const OLD_OPEN: [Step; 2] = [Step::Dtr(false), Step::Rts(false)];

/// ESP32-C3 TRM, Table 30.4-1 "Reset SoC into Download Mode".
const TABLE_30_4_1: [Step; 8] = [
    Step::Dtr(false),
    Step::Rts(false),
    Step::Dtr(true),
    Step::Rts(false),
    Step::Rts(true),
    Step::Dtr(false),
    Step::Rts(true),
    Step::Rts(false),
];

/// ESP32-C3 TRM, Table 30.4-2 "Reset SoC into Booting".
const TABLE_30_4_2: [Step; 4] = [
    Step::Dtr(false),
    Step::Rts(false),
    Step::Rts(true),
    Step::Rts(false),
];

fn options() -> Options {
    Options {
        timeout: Duration::from_millis(100),
        retries: 2,
        poll_interval: Duration::from_millis(2),
    }
}

fn twin() -> TwinOptions {
    TwinOptions {
        seed: 32,
        ..TwinOptions::default()
    }
}

fn params() -> RunParams {
    JointSpec::default()
        .run_params(GaugeGeometry::PAPER)
        .unwrap()
}

fn write(port: &mut dyn SerialPort, steps: &[Step]) {
    for step in steps {
        match *step {
            Step::Dtr(level) => port.write_data_terminal_ready(level),
            Step::Rts(level) => port.write_request_to_send(level),
        }
        .unwrap();
    }
}

/// Make the device ready and measure the gauge under it.
fn measure(meter: &mut Kerfmeter) -> kerfmeter::Result<KerfResult> {
    meter.prepare_for_run()?;
    meter.run_kerfmeter(&params(), |_| {})
}

/// One command as the CLI runs one: the OS opens the port, `before` writes lines (nothing, or the
/// old order), the client opens the device, `call`, the port is closed. The boot id the client
/// saw, and what the call returned.
fn command<T>(
    c3: &C3,
    before: &[Step],
    call: impl FnOnce(&mut Kerfmeter) -> kerfmeter::Result<T>,
) -> (u32, kerfmeter::Result<T>) {
    let mut port = c3.open();
    write(&mut *port, before);
    let mut meter = Kerfmeter::from_port(port, options()).expect("the device answers GetInfo");
    let out = call(&mut meter);
    (meter.cached_info().boot_id, out)
}

fn resets(requests: &[LineRequest]) -> Vec<LineRequest> {
    let reset = |r: &&LineRequest| matches!(r.action, Action::Reset { .. });
    requests.iter().filter(reset).copied().collect()
}

/// A hundred commands through `driver`: one measurement, then 99 reads of its result, each
/// opening and closing the port. Every one sees the same boot and the result; the chip is never
/// reset, and its flag is clear and its lines released after each. The requests it received.
fn hundred_commands(driver: Driver) -> Vec<LineRequest> {
    let c3 = C3::new(twin(), driver);
    let (first_boot, kerf) = command(&c3, &[], measure);
    let kerf = kerf.expect("the twin measures its gauge");
    let mut boots = BTreeSet::from([first_boot]);
    for i in 1..COMMANDS {
        let (boot, last) = command(&c3, &[], Kerfmeter::get_kerf_value);
        boots.insert(boot);
        assert_eq!(last.unwrap(), Some(kerf), "command {i}: the result is kept");
        assert_eq!((c3.pair(), c3.download_flag()), (Pair::RELEASED, false));
    }
    let requests = c3.requests();
    eprintln!(
        "{driver:?}: {COMMANDS} commands, boot ids seen {boots:x?}, {} requests to the chip, \
         {} of them changing the pair, {} resets, {} set the download flag",
        requests.len(),
        requests.iter().filter(|r| r.before != r.pair).count(),
        c3.resets(),
        requests
            .iter()
            .filter(|r| r.action == Action::SetDownloadFlag)
            .count(),
    );
    assert_eq!(boots.len(), 1, "boot ids {boots:x?}");
    assert_eq!(resets(&requests), vec![]);
    requests
}

#[test]
fn a_hundred_commands_on_linux_see_one_boot() {
    let requests = hundred_commands(Driver::LINUX_CDC_ACM);
    // Per command: open raises both (nothing), RTS released (the flag set), DTR released (the
    // flag cleared), RTS written again (unchanged: nothing sent), close lowers both (cleared).
    let rts_released = Pair {
        dtr: true,
        rts: false,
    };
    let one = [
        (Source::Open, Pair::RAISED, Action::Nothing),
        (Source::Write, rts_released, Action::SetDownloadFlag),
        (Source::Write, Pair::RELEASED, Action::ClearDownloadFlag),
        (Source::Close, Pair::RELEASED, Action::ClearDownloadFlag),
    ];
    assert_eq!(requests.len(), one.len() * COMMANDS);
    for (i, r) in requests.iter().enumerate() {
        assert_eq!(
            (r.source, r.pair, r.action),
            one[i % one.len()],
            "request {i}"
        );
    }
}

#[test]
fn a_hundred_commands_on_windows_see_one_boot() {
    let requests = hundred_commands(Driver::WINDOWS_USBSER);
    // DTR waits for the RTS writes, each of which sends (0, 0).
    assert_eq!(requests.len(), 2 * COMMANDS);
    let cleared = |r: &LineRequest| r.pair == Pair::RELEASED && r.source == Source::Write;
    assert!(requests.iter().all(cleared), "{requests:?}");
}

#[test]
fn the_old_order_reboots_the_chip_at_every_open_and_loses_the_result() {
    let c3 = C3::new(twin(), Driver::LINUX_CDC_ACM);
    let (first_boot, kerf) = command(&c3, &[], measure);
    assert!(kerf.is_ok());
    let mut boots = BTreeSet::from([first_boot]);
    for _ in 0..3 {
        let (boot, last) = command(&c3, &OLD_OPEN, Kerfmeter::get_kerf_value);
        boots.insert(boot);
        assert_eq!(last.unwrap(), None, "the reset lost the result");
    }
    assert_eq!(
        boots.len(),
        4,
        "a new boot at each old-order open: {boots:x?}"
    );
    let resets = resets(&c3.requests());
    assert_eq!(resets.len(), 3);
    for r in resets {
        // DTR released first, under the RTS the OS raised: the chip's reset pair.
        assert_eq!((r.source, r.before), (Source::Write, Pair::RAISED));
        let reset_pair = Pair {
            dtr: false,
            rts: true,
        };
        assert_eq!(r.pair, reset_pair);
        assert_eq!(
            r.action,
            Action::Reset {
                into_download: false
            }
        );
    }
}

#[test]
fn confirm_zero_then_run_as_two_commands_runs_and_the_old_order_refused_it() {
    let motor_shaft = TwinOptions {
        encoder_on_motor_shaft: true,
        ..twin()
    };
    let confirm_then_run = |before: &[Step]| {
        let c3 = C3::new(motor_shaft, Driver::LINUX_CDC_ACM);
        command(&c3, before, Kerfmeter::confirm_hub_at_zero)
            .1
            .unwrap();
        command(&c3, before, measure).1
    };
    assert!(confirm_then_run(&[]).is_ok());
    match confirm_then_run(&OLD_OPEN) {
        Err(Error::Device {
            code: ErrorCode::Blocked(conditions),
            ..
        }) => assert!(conditions.contains(Conditions::HUB_TURN_UNKNOWN)),
        other => panic!("the rebooted device should refuse the run: {other:?}"),
    }
}

#[test]
fn every_pair_an_os_may_open_with_is_released_without_a_reset_and_with_the_flag_clear() {
    for base in [Driver::LINUX_CDC_ACM, Driver::WINDOWS_USBSER] {
        for opened in Pair::ALL {
            for flag in [false, true] {
                let driver = Driver {
                    on_open: Some(opened),
                    ..base
                };
                let c3 = C3::new(twin(), driver);
                c3.set_download_flag(flag);
                let meter = Kerfmeter::from_port(c3.open(), options());
                let case = format!("{driver:?}, flag {flag}");
                let writes = c3
                    .requests()
                    .into_iter()
                    .filter(|r| r.source == Source::Write);
                assert_eq!(resets(&writes.collect::<Vec<_>>()), vec![], "{case}");
                assert_eq!(
                    (c3.pair(), c3.download_flag()),
                    (Pair::RELEASED, false),
                    "{case}"
                );
                // Unless the OS's own open reset the chip, nothing did, and the device answers.
                if c3.resets() == 0 {
                    meter.expect(&case);
                }
            }
        }
    }
}

#[test]
fn a_vanished_port_is_opened_again_on_the_same_boot_with_the_result_kept() {
    let c3 = C3::new(twin(), Driver::LINUX_CDC_ACM);
    let mut meter = Kerfmeter::from_port(c3.open(), options()).unwrap();
    let kerf = measure(&mut meter).unwrap();
    let boot = meter.cached_info().boot_id;
    c3.vanish();
    let err = meter.get_kerf_value().unwrap_err();
    assert!(matches!(err, Error::PortVanished { .. }), "{err:?}");
    drop(meter);
    c3.reappear();
    let (again, last) = command(&c3, &[], Kerfmeter::get_kerf_value);
    assert_eq!((again, last.unwrap()), (boot, Some(kerf)));
    assert_eq!(c3.resets(), 0);
}

#[test]
fn a_port_that_refuses_rts_is_left_as_the_os_opened_it() {
    let driver = Driver {
        rts_refused: true,
        ..Driver::LINUX_CDC_ACM
    };
    let c3 = C3::new(twin(), driver);
    let mut port = c3.open();
    assert!(kerfmeter::lines::release(&mut *port).is_err());
    // DTR was not released alone under the raised RTS.
    assert_eq!(c3.pair(), Pair::RAISED);
    let meter = Kerfmeter::from_port(port, options()).unwrap();
    assert_eq!(c3.resets(), 0);
    drop(meter);
    assert_eq!(c3.requests().len(), 2, "open and close only");
}

/// The double itself, against Espressif's documented sequences (TRM §30.4): Table 30.4-2
/// reboots the firmware (a new boot id); Table 30.4-1 leaves the chip in the ROM's download
/// mode, where the device answers nothing, until Table 30.4-2 boots it again.
#[test]
fn the_double_resets_the_chip_as_espressifs_sequences_say() {
    let c3 = C3::new(twin(), Driver::LINUX_CDC_ACM);
    let (first, _) = command(&c3, &[], Kerfmeter::info);
    let (rebooted, _) = command(&c3, &TABLE_30_4_2, Kerfmeter::info);
    assert_ne!(rebooted, first);
    assert!(!c3.in_download_mode());

    let mut port = c3.open();
    write(&mut *port, &TABLE_30_4_1);
    assert!(c3.in_download_mode());
    assert!(
        !c3.download_flag(),
        "the table clears the flag as its last step"
    );
    let err = Kerfmeter::from_port(port, options()).unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err:?}");

    let (booted, _) = command(&c3, &TABLE_30_4_2, Kerfmeter::info);
    assert!(!c3.in_download_mode());
    assert!(![first, rebooted].contains(&booted));
    let into_download = |r: &LineRequest| {
        r.action
            == Action::Reset {
                into_download: true,
            }
    };
    assert_eq!(c3.requests().iter().filter(|r| into_download(r)).count(), 1);
}
