//! `cargo xtask bench-step`: how many instructions one `Controller::step` and one kerf solve take
//! on the ESP32-C3's instruction set, and the CPU share that implies at the control rate.
//!
//! Host timings say nothing about an FPU-less RV32IMC core, where every `f32` operation is a
//! soft-float library call. So the benchmark program `firmware-esp32/bench-rv32` (outside the
//! workspace) links the real firmware library, is built for `riscv32imc-unknown-none-elf` with
//! the firmware image's profile, and runs on `qemu-system-riscv32`'s `virt` machine with
//! `-icount shift=0`, where the `minstret` counter is exact. The program reads `minstret` and
//! `mcycle` around each measured call; this task builds it, checks that it is soft-float,
//! installs qemu (Debian's `qemu-system-misc`) if it is missing, runs it, and prints the table.
//!
//! Cycles on the chip are instructions × CPI. The C3's core is a 4-stage in-order pipeline:
//! the table assumes a CPI between 1 and 1.5 (branches, loads and the multi-cycle divider),
//! running from cache. Code and constants come from external flash through the cache, and every
//! cache miss costs tens of cycles more, so the real figure can be higher than the table's upper
//! bound. qemu's `mcycle` is only its instruction count again (it has no pipeline model).
//!
//! With `--json` it prints only the figures the firmware's targets are set on, as one JSON object
//! on stdout (everything else goes to stderr):
//!
//! ```text
//! {"step_mean_instructions": …, "step_worst_instructions": …, "kerf_solve_instructions": …}
//! ```
//!
//! the mean Ramping step (the busiest state), the worst step in any state, and the mean kerf
//! solve over all angles; instructions, rounded to whole ones.
//!
//! This is a benchmark, not a test: `cargo xtask test` does not run it.

use std::collections::BTreeMap;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use object::elf::{EF_RISCV_FLOAT_ABI, EF_RISCV_FLOAT_ABI_SOFT, EF_RISCV_RVC, EM_RISCV};
use object::read::elf::{ElfFile32, FileHeader};
use object::{Endianness, Object, ObjectSection, ObjectSymbol, SectionKind};

use crate::{cargo, root, run_cmd};

/// The benchmark crate, relative to the workspace root.
const BENCH_DIR: &str = "firmware-esp32/bench-rv32";
/// Its binary.
const BENCH_BIN: &str = "kerfmeter-bench-rv32";
/// The ESP32-C3's target: RV32IMC, no FPU.
const TARGET: &str = "riscv32imc-unknown-none-elf";
/// The firmware image's profile (root `Cargo.toml`); the bench crate defines the same one.
const PROFILE: &str = "firmware";
/// The emulator.
const QEMU: &str = "qemu-system-riscv32";
/// The Debian package that has it.
const QEMU_PACKAGE: &str = "qemu-system-misc";
/// The benchmark takes about a second; give up on a hung emulator after this.
const QEMU_TIMEOUT: Duration = Duration::from_secs(120);
/// Soft-float routines that must be linked (the program does `f32` arithmetic through them).
const SOFT_FLOAT_SYMBOLS: [&str; 3] = ["__addsf3", "__mulsf3", "__divsf3"];
/// Assumed cycles per instruction on the ESP32-C3, from cache: best and worst.
const CPI_RANGE: (f64, f64) = (1.0, 1.5);

/// Issue 12's targets, instructions: the mean Ramping step (5 % of a 160 MHz core at 1 kHz)
/// and the worst step in any state. The counts are exact (minstret under `-icount`), not timed,
/// so the command fails when a change passes them.
const TARGET_MEAN_STEP: u64 = 8_000;
const TARGET_WORST_STEP: u64 = 16_000;

/// `cargo xtask bench-step` options.
#[derive(clap::Args)]
pub struct BenchArgs {
    /// Core clock the CPU share is computed for, MHz (the ESP32-C3 runs at 160).
    #[arg(long, default_value_t = 160.0)]
    pub clock_mhz: f64,
    /// Control rate, Hz (the firmware steps at 1 kHz).
    #[arg(long, default_value_t = 1000.0)]
    pub rate_hz: f64,
    /// Also print the benchmark program's raw output (to stderr with `--json`).
    #[arg(long)]
    pub raw: bool,
    /// Print only the target figures as one JSON object on stdout: `step_mean_instructions`
    /// (mean Ramping step), `step_worst_instructions` (worst step in any state) and
    /// `kerf_solve_instructions` (mean kerf solve).
    #[arg(long)]
    pub json: bool,
}

/// `cargo xtask bench-step`.
pub fn step(args: &BenchArgs) -> Result<()> {
    crate::firmware::ensure_targets()?;
    check_profile_matches()?;
    let elf = build()?;
    let float = check_soft_float(&elf)?;
    ensure_qemu()?;
    let output = run_qemu(&elf)?;
    let report = Report::parse(&output)?;
    if args.json {
        if args.raw {
            eprintln!("{output}");
        }
        eprintln!("{float}");
        eprint!("{}", report.table(args.clock_mhz, args.rate_hz));
        println!("{}", report.summary()?);
    } else {
        if args.raw {
            println!("{output}");
        }
        println!("{float}");
        print!("{}", report.table(args.clock_mhz, args.rate_hz));
    }
    report.check_targets()
}

/// The settings of `[profile.<name>]` in a `Cargo.toml` (plain `key = value` lines).
fn profile_settings(manifest: &str, name: &str) -> BTreeMap<String, String> {
    let header = format!("[profile.{name}]");
    let mut settings = BTreeMap::new();
    let mut inside = false;
    for line in manifest.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.starts_with('[') {
            inside = line == header;
            continue;
        }
        if inside && let Some((key, value)) = line.split_once('=') {
            settings.insert(key.trim().to_string(), value.trim().to_string());
        }
    }
    settings
}

/// The bench crate must compile the library exactly as the firmware image does.
fn check_profile_matches() -> Result<()> {
    let read = |path: PathBuf| {
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))
    };
    let workspace = profile_settings(&read(root().join("Cargo.toml"))?, PROFILE);
    let bench = profile_settings(&read(root().join(BENCH_DIR).join("Cargo.toml"))?, PROFILE);
    if workspace.is_empty() {
        bail!("the root Cargo.toml has no [profile.{PROFILE}]");
    }
    if workspace != bench {
        bail!(
            "[profile.{PROFILE}] of {BENCH_DIR}/Cargo.toml ({bench:?}) differs from the \
             workspace's ({workspace:?}): copy the workspace's settings"
        );
    }
    Ok(())
}

/// Build the benchmark program; the path of its ELF.
fn build() -> Result<PathBuf> {
    let manifest = root().join(BENCH_DIR).join("Cargo.toml");
    let mut cmd = cargo();
    cmd.arg("build")
        .arg("--manifest-path")
        .arg(&manifest)
        .args(["--bin", BENCH_BIN, "--target", TARGET, "--profile", PROFILE]);
    // The workspace's target folder, unless the caller chose one (the bench crate is its own
    // workspace, whose default would be a `target/` inside it).
    if std::env::var_os("CARGO_TARGET_DIR").is_none() {
        cmd.arg("--target-dir").arg(root().join("target"));
    }
    cmd.arg("--message-format=json-render-diagnostics")
        .stdout(Stdio::piped());
    eprintln!("$ {}", crate::show(&cmd));
    let mut child = cmd.spawn().context("cannot start cargo")?;
    let stdout = child.stdout.take().expect("stdout is piped");
    let mut elf = None;
    for line in std::io::BufReader::new(stdout).lines() {
        let line = line.context("reading cargo's output")?;
        let Ok(message) = serde_json::from_str::<serde_json::Value>(&line) else {
            continue;
        };
        if message["reason"] == "compiler-artifact"
            && let Some(path) = message["executable"].as_str()
        {
            elf = Some(PathBuf::from(path));
        }
    }
    let status = child.wait().context("waiting for cargo")?;
    if !status.success() {
        bail!("building {BENCH_DIR} failed ({status})");
    }
    elf.context("cargo built no benchmark executable")
}

/// What the soft-float check found.
struct FloatCheck {
    soft_float_symbols: Vec<&'static str>,
    text_bytes: u64,
}

impl std::fmt::Display for FloatCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "soft-float checked: RV32 ELF with the soft-float ABI and RVC, no F/D instruction in \
             {} bytes of code, soft-float routines linked ({}); qemu ran with F and D disabled",
            self.text_bytes,
            self.soft_float_symbols.join(", ")
        )
    }
}

/// Check that the program is RV32IMC soft-float: the ELF's float ABI is soft, no instruction in
/// its code belongs to the F or D extension, and the soft-float routines are linked. (qemu also
/// runs it with F and D disabled, so an F instruction would trap.)
fn check_soft_float(elf: &Path) -> Result<FloatCheck> {
    let data = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file = ElfFile32::<Endianness>::parse(&*data)
        .with_context(|| format!("{} is not a 32-bit ELF", elf.display()))?;
    let header = file.elf_header();
    let endian = file.endian();
    if header.e_machine(endian) != EM_RISCV {
        bail!("{} is not a RISC-V ELF", elf.display());
    }
    let flags = header.e_flags(endian);
    if flags & EF_RISCV_FLOAT_ABI != EF_RISCV_FLOAT_ABI_SOFT {
        bail!(
            "{} does not use the soft-float ABI (e_flags {flags:#x})",
            elf.display()
        );
    }
    if flags & EF_RISCV_RVC == 0 {
        bail!(
            "{} is not built with compressed instructions (RVC)",
            elf.display()
        );
    }
    let mut text_bytes = 0;
    for section in file.sections() {
        if section.kind() != SectionKind::Text {
            continue;
        }
        let code = section.data().context("reading a code section")?;
        text_bytes += code.len() as u64;
        if let Some((offset, word)) = first_float_instruction(code) {
            bail!(
                "{} has an F/D instruction ({word:#x}) at {:#x}: not soft-float",
                elf.display(),
                section.address() + offset as u64
            );
        }
    }
    let linked: Vec<&'static str> = SOFT_FLOAT_SYMBOLS
        .into_iter()
        .filter(|name| file.symbols().any(|s| s.name() == Ok(*name)))
        .collect();
    if linked.len() != SOFT_FLOAT_SYMBOLS.len() {
        bail!(
            "{} does not link the soft-float routines {SOFT_FLOAT_SYMBOLS:?} (found {linked:?})",
            elf.display()
        );
    }
    Ok(FloatCheck {
        soft_float_symbols: linked,
        text_bytes,
    })
}

/// The first F- or D-extension instruction in RISC-V code (16- and 32-bit encodings), as
/// `(byte offset, encoding)`.
fn first_float_instruction(code: &[u8]) -> Option<(usize, u32)> {
    let mut at = 0;
    while at + 2 <= code.len() {
        let low = u16::from_le_bytes([code[at], code[at + 1]]);
        if low & 0b11 == 0b11 {
            if at + 4 > code.len() {
                break;
            }
            let word = u32::from(low)
                | (u32::from(u16::from_le_bytes([code[at + 2], code[at + 3]])) << 16);
            // LOAD-FP, STORE-FP, FMADD, FMSUB, FNMSUB, FNMADD, OP-FP.
            if matches!(
                word & 0x7F,
                0b000_0111
                    | 0b010_0111
                    | 0b100_0011
                    | 0b100_0111
                    | 0b100_1011
                    | 0b100_1111
                    | 0b101_0011
            ) {
                return Some((at, word));
            }
            at += 4;
        } else {
            // Compressed: c.fld / c.flw / c.fsd / c.fsw (quadrant 0) and their stack-pointer forms
            // (quadrant 2) have funct3 001, 011, 101, 111 on RV32.
            let quadrant = low & 0b11;
            let funct3 = low >> 13;
            if matches!(quadrant, 0b00 | 0b10) && funct3 & 1 == 1 {
                return Some((at, u32::from(low)));
            }
            at += 2;
        }
    }
    None
}

/// Install qemu-system-riscv32 if it is missing (Debian's `qemu-system-misc`, as root).
fn ensure_qemu() -> Result<()> {
    if qemu_present() {
        return Ok(());
    }
    eprintln!("{QEMU} is missing: installing Debian's {QEMU_PACKAGE} with apt-get");
    let root_user = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    let apt = Command::new("apt-get").arg("--version").output().is_ok();
    if !(root_user && apt) {
        bail!(
            "{QEMU} is not installed and cannot be installed from here (needs apt-get as root): \
             install the `{QEMU_PACKAGE}` package (Debian/Ubuntu) or your system's qemu with the \
             riscv32 system emulator"
        );
    }
    run_cmd(Command::new("apt-get").args(["update", "-qq"]))?;
    run_cmd(
        Command::new("apt-get")
            .args([
                "install",
                "-y",
                "-qq",
                "--no-install-recommends",
                QEMU_PACKAGE,
            ])
            .env("DEBIAN_FRONTEND", "noninteractive"),
    )?;
    if !qemu_present() {
        bail!("{QEMU_PACKAGE} was installed but {QEMU} still does not run");
    }
    Ok(())
}

fn qemu_present() -> bool {
    Command::new(QEMU)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Run the program on qemu's virt machine; its UART output. Fails unless it exits with status 0.
fn run_qemu(elf: &Path) -> Result<String> {
    let mut cmd = Command::new(QEMU);
    cmd.args(["-machine", "virt"])
        // A generic RV32 core with the F and D extensions off: a hard-float instruction traps.
        .args(["-cpu", "rv32,f=off,d=off"])
        .args(["-bios", "none"])
        // One instruction per virtual nanosecond: minstret is exact.
        .args(["-icount", "shift=0"])
        .args(["-nographic", "-monitor", "none", "-serial", "stdio"])
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    eprintln!("$ {}", crate::show(&cmd));
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start {QEMU}"))?;
    let mut stdout = child.stdout.take().expect("stdout is piped");
    let mut stderr = child.stderr.take().expect("stderr is piped");
    let out_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().context("waiting for qemu")? {
            break status;
        }
        if started.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            let out = out_reader.join().unwrap_or_default();
            bail!(
                "{QEMU} did not finish within {} s; output so far:\n{out}",
                QEMU_TIMEOUT.as_secs()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let out = out_reader.join().unwrap_or_default();
    let err = err_reader.join().unwrap_or_default();
    if !status.success() || !out.lines().any(|l| l.trim() == "DONE") {
        bail!("the benchmark failed ({status}):\n{out}{err}");
    }
    Ok(out)
}

/// One `STAT` record: instructions per call, net of the measuring bracket.
#[derive(Debug, Clone, PartialEq)]
struct Stat {
    group: String,
    name: String,
    calls: u64,
    sum: u64,
    min: u64,
    max: u64,
}

impl Stat {
    fn mean(&self) -> f64 {
        self.sum as f64 / self.calls as f64
    }
}

/// The benchmark's output, parsed.
#[derive(Debug)]
struct Report {
    overhead: u64,
    calibration: (u64, u64),
    stats: Vec<Stat>,
    runs: Vec<String>,
}

impl Report {
    fn parse(output: &str) -> Result<Self> {
        let mut overhead = None;
        let mut calibration = None;
        let mut stats = Vec::new();
        let mut runs = Vec::new();
        for line in output.lines().map(str::trim) {
            let mut words = line.split_whitespace();
            let Some(kind) = words.next() else { continue };
            let fields = |words: std::str::SplitWhitespace<'_>| -> BTreeMap<String, String> {
                words
                    .filter_map(|w| w.split_once('='))
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect()
            };
            let number = |f: &BTreeMap<String, String>, key: &str| -> Result<u64> {
                f.get(key)
                    .with_context(|| format!("`{key}` missing in `{line}`"))?
                    .parse()
                    .with_context(|| format!("`{key}` is not a number in `{line}`"))
            };
            match kind {
                "CAL" => {
                    let f = fields(words);
                    overhead = Some(number(&f, "overhead")?);
                    calibration = Some((number(&f, "loop")?, number(&f, "expected")?));
                }
                "STAT" => {
                    let group = words.next().context("STAT without a group")?.to_string();
                    let name = words.next().context("STAT without a name")?.to_string();
                    let f = fields(words);
                    let stat = Stat {
                        group,
                        name,
                        calls: number(&f, "calls")?,
                        sum: number(&f, "sum")?,
                        min: number(&f, "min")?,
                        max: number(&f, "max")?,
                    };
                    if stat.calls == 0 {
                        bail!("no call measured in `{line}`");
                    }
                    stats.push(stat);
                }
                "RUN" => runs.push(line.to_string()),
                _ => {}
            }
        }
        let calibration = calibration.context("no CAL line in the benchmark's output")?;
        if calibration.0 != calibration.1 {
            bail!(
                "minstret is not exact: {} instructions counted for a loop of {}",
                calibration.0,
                calibration.1
            );
        }
        if stats.is_empty() {
            bail!("no STAT line in the benchmark's output");
        }
        Ok(Self {
            overhead: overhead.context("no overhead in the CAL line")?,
            calibration,
            stats,
            runs,
        })
    }

    fn find(&self, group: &str, name: &str) -> Option<&Stat> {
        self.stats
            .iter()
            .find(|s| s.group == group && s.name == name)
    }

    /// The target figures (`--json`): mean Ramping step, worst step in any state, mean kerf
    /// solve, in whole instructions; one JSON object, its keys in that order.
    fn summary(&self) -> Result<String> {
        let (mean, worst) = self.step_figures()?;
        let kerf = self.stat("kerf", "all")?;
        Ok(format!(
            "{{\"step_mean_instructions\": {mean}, \"step_worst_instructions\": {worst}, \
             \"kerf_solve_instructions\": {}}}",
            kerf.mean().round() as u64,
        ))
    }

    /// A statistic the benchmark must have printed.
    fn stat(&self, group: &str, name: &str) -> Result<&Stat> {
        self.find(group, name)
            .with_context(|| format!("no `STAT {group} {name}` in the benchmark's output"))
    }

    /// The figures the targets are on, whole instructions: the mean Ramping step and the worst
    /// step in any state.
    fn step_figures(&self) -> Result<(u64, u64)> {
        let mean = self.stat("step", "ramping")?.mean().round() as u64;
        Ok((mean, self.stat("step", "all")?.max))
    }

    /// Fail when the mean Ramping step or the worst step passes its target
    /// ([`TARGET_MEAN_STEP`], [`TARGET_WORST_STEP`]).
    fn check_targets(&self) -> Result<()> {
        let (mean, worst) = self.step_figures()?;
        anyhow::ensure!(
            mean <= TARGET_MEAN_STEP && worst <= TARGET_WORST_STEP,
            "the control step is over its targets: mean Ramping step {mean} instructions (target \
             {TARGET_MEAN_STEP}), worst step {worst} (target {TARGET_WORST_STEP})"
        );
        Ok(())
    }

    /// The table, with CPU shares at `rate_hz` steps per second on a `clock_mhz` core.
    fn table(&self, clock_mhz: f64, rate_hz: f64) -> String {
        use std::fmt::Write;
        let (cpi_lo, cpi_hi) = CPI_RANGE;
        // Percent of the CPU for `instructions` once per control period.
        let share =
            |instructions: f64, cpi: f64| instructions * cpi * rate_hz / (clock_mhz * 1e6) * 100.0;
        let us = |instructions: f64, cpi: f64| instructions * cpi / clock_mhz;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "\nInstructions per call on RV32IMC (riscv32imc-unknown-none-elf, soft-float, profile \
             `{PROFILE}`), counted with minstret under qemu -icount shift=0 (calibration: \
             {} of {} exact; bracket overhead {} subtracted).",
            self.calibration.0, self.calibration.1, self.overhead
        );
        let _ = writeln!(
            t,
            "Time and CPU share at {rate_hz:.0} Hz on a {clock_mhz:.0} MHz core without FPU, \
             assuming CPI {cpi_lo}–{cpi_hi}:\n"
        );
        let _ = writeln!(
            t,
            "{:<40} {:>6} {:>8} {:>8} {:>8}   {:>15}   {:>13}   {:>13}",
            "call", "calls", "mean", "min", "max", "mean µs", "mean CPU %", "max CPU %"
        );
        let mut row = |label: String, s: &Stat| {
            let mean = s.mean();
            let max = s.max as f64;
            let _ = writeln!(
                t,
                "{label:<40} {:>6} {:>8.0} {:>8} {:>8}   {:>6.1} – {:<6.1}   {:>5.1} – {:<5.1}   {:>5.1} – {:<5.1}",
                s.calls,
                mean,
                s.min,
                s.max,
                us(mean, cpi_lo),
                us(mean, cpi_hi),
                share(mean, cpi_lo),
                share(mean, cpi_hi),
                share(max, cpi_lo),
                share(max, cpi_hi),
            );
        };
        for s in self.stats.iter().filter(|s| s.group == "kerf") {
            let label = match s.name.strip_prefix("angle=") {
                Some(angle) => format!("kerf_from_angle, θm = {angle}°"),
                None => "kerf_from_angle, all angles".to_string(),
            };
            row(label, s);
        }
        for s in self.stats.iter().filter(|s| s.group == "step") {
            let label = if s.name == "all" {
                "Controller::step, all states".to_string()
            } else {
                format!("Controller::step, {}", s.name)
            };
            row(label, s);
        }
        for s in self.stats.iter().filter(|s| s.group == "part") {
            row(format!("  part of a step: {}", s.name), s);
        }
        let _ = writeln!(t);
        for run in &self.runs {
            let _ = writeln!(t, "{run}");
        }
        if let Some(ramping) = self.find("step", "ramping") {
            let _ = writeln!(
                t,
                "\nBusiest state: Ramping, {:.0} instructions per step on average, {} at most: \
                 {:.1}–{:.1} % of the CPU on average at {rate_hz:.0} Hz, {:.1}–{:.1} % at worst.",
                ramping.mean(),
                ramping.max,
                share(ramping.mean(), cpi_lo),
                share(ramping.mean(), cpi_hi),
                share(ramping.max as f64, cpi_lo),
                share(ramping.max as f64, cpi_hi),
            );
        }
        let _ = writeln!(
            t,
            "Assumptions: CPI {cpi_lo}–{cpi_hi} with code and data in cache. The ESP32-C3 runs code \
             from external flash through its cache: misses add tens of cycles each and can push \
             the figures above the upper bound. Not included: Hardware::tick's SPI transfers, GPIO \
             and ADC, the link, and interrupts."
        );
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OUTPUT: &str = "\
kerfmeter-bench-rv32: Controller::step and kerf_from_angle on RV32IMC (soft-float)
CAL overhead=5 loop=2001 expected=2001
KERF angle_deg=45 kerf_um=110.57214 converged=true
STAT kerf angle=45 calls=100 sum=787100 min=7871 max=7871 cycles_sum=787100 cycles_min=7871 cycles_max=7871
STAT kerf all calls=100 sum=787100 min=7871 max=7871 cycles_sum=787100 cycles_min=7871 cycles_max=7871
RUN hold_deg=45 kerf_um=110.57214 flags=0x0000 ticks=1548
STAT step ramping calls=4 sum=120000 min=24000 max=40000 cycles_sum=120000 cycles_min=24000 cycles_max=40000
STAT step all calls=6 sum=120400 min=150 max=40000 cycles_sum=120400 cycles_min=150 cycles_max=40000
DONE
";

    #[test]
    fn the_output_is_parsed() {
        let r = Report::parse(OUTPUT).unwrap();
        assert_eq!(r.overhead, 5);
        assert_eq!(r.calibration, (2001, 2001));
        assert_eq!(r.stats.len(), 4);
        let ramping = r.find("step", "ramping").unwrap();
        assert_eq!((ramping.calls, ramping.min, ramping.max), (4, 24000, 40000));
        assert_eq!(ramping.mean(), 30000.0);
        assert_eq!(r.runs.len(), 1);
    }

    #[test]
    fn the_json_summary_has_the_target_figures() {
        let r = Report::parse(OUTPUT).unwrap();
        let summary = r.summary().unwrap();
        assert_eq!(
            summary,
            r#"{"step_mean_instructions": 30000, "step_worst_instructions": 40000, "kerf_solve_instructions": 7871}"#
        );
        let parsed: serde_json::Value = serde_json::from_str(&summary).unwrap();
        assert_eq!(parsed["step_worst_instructions"], 40000);
        // Without a Ramping step there is no mean step to report.
        let no_ramp =
            Report::parse(&OUTPUT.replace("STAT step ramping", "STAT step jammed")).unwrap();
        assert!(no_ramp.summary().is_err());
    }

    #[test]
    fn steps_over_their_targets_fail_the_command() {
        // The sample output's Ramping steps average 30,000 instructions.
        let over = Report::parse(OUTPUT).unwrap();
        let e = over.check_targets().unwrap_err().to_string();
        assert!(e.contains("30000") && e.contains("8000"), "{e}");
        let scaled = OUTPUT
            .replace(
                "STAT step ramping calls=4 sum=120000 min=24000 max=40000 cycles_sum=120000 cycles_min=24000 cycles_max=40000",
                "STAT step ramping calls=4 sum=28000 min=6000 max=9000 cycles_sum=28000 cycles_min=6000 cycles_max=9000",
            )
            .replace(
                "STAT step all calls=6 sum=120400 min=150 max=40000 cycles_sum=120400 cycles_min=150 cycles_max=40000",
                "STAT step all calls=6 sum=28400 min=150 max=9000 cycles_sum=28400 cycles_min=150 cycles_max=9000",
            );
        let within = Report::parse(&scaled).unwrap();
        assert!(
            within.check_targets().is_ok(),
            "{}",
            within.summary().unwrap()
        );
    }

    #[test]
    fn an_inexact_counter_is_refused() {
        let bad = OUTPUT.replace("loop=2001", "loop=2048");
        assert!(Report::parse(&bad).is_err());
    }

    #[test]
    fn the_cpu_share_follows_from_instructions_clock_and_rate() {
        let r = Report::parse(OUTPUT).unwrap();
        let table = r.table(160.0, 1000.0);
        // 30000 instructions at CPI 1 on 160 MHz: 187.5 µs per 1 ms tick = 18.75 %.
        assert!(table.contains("18.8 – 28.1"), "{table}");
    }

    #[test]
    fn float_instructions_are_found() {
        // addi a0, a0, 1 ; c.addi a0, 1 ; then fadd.s f0, f0, f0.
        let mut code = Vec::new();
        code.extend_from_slice(&0x0015_0513u32.to_le_bytes());
        code.extend_from_slice(&0x0505u16.to_le_bytes());
        assert_eq!(first_float_instruction(&code), None);
        code.extend_from_slice(&0x0000_7053u32.to_le_bytes());
        assert_eq!(first_float_instruction(&code), Some((6, 0x0000_7053)));
        // c.flwsp f8, 0(sp) (quadrant 2, funct3 011).
        let compressed = 0x6402u16.to_le_bytes();
        assert_eq!(first_float_instruction(&compressed), Some((0, 0x6402)));
    }

    #[test]
    fn profile_settings_are_read() {
        let toml = "[profile.release]\ndebug = 1\n\n[profile.firmware]\ninherits = \"release\"\n\
                    opt-level = \"s\" # small\nlto = \"fat\"\n\n[profile.dev]\nopt-level = 1\n";
        let s = profile_settings(toml, "firmware");
        assert_eq!(s.len(), 3);
        assert_eq!(s["opt-level"], "\"s\"");
    }
}
