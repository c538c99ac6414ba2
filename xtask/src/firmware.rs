//! `cargo xtask firmware`: build the board image for a chip and check its flash and RAM budget,
//! or (`--check`) run clippy on the board binary for that chip's target.
//!
//! The chip builds need `--target` and a chip feature, which plain `cargo build` from the
//! workspace root does not add: this module is the one place that knows the pairs.
//!
//! # How the sizes are counted
//!
//! From the ELF's section headers, allocated (`SHF_ALLOC`) sections only:
//!
//! - **Flash** = every allocated section with contents in the file (`PROGBITS`): code and
//!   read-only data that run from flash (`.text`, `.rodata`, `.flash.appdesc`) plus the load
//!   images of what the startup code copies into RAM (`.trap`, `.rwtext`, `.data`,
//!   `.rtc_fast.*`). The espflash image adds a few headers and padding on top.
//! - **Static RAM** = every allocated section placed outside the chip's flash-mapped address
//!   windows: `.trap`/`.rwtext` (code in RAM), `.data`, `.bss`, `.noinit`, `.rtc_fast.*`.
//! - **Not counted**: esp-hal's linker placeholders, which only reserve address space: `.stack`
//!   (the rest of RAM, handed to the stack), `.rwdata_dummy` (the C3's data-bus alias of the RAM
//!   that `.trap`/`.rwtext` already use), `.rotext_dummy` / `.text_gap` (flash address space
//!   skipped so that code and data do not share an MMU page). Plain `size` counts them, which is
//!   why it reports hundreds of KiB.

use std::fmt;
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};

use crate::{cargo, root, run_cmd, show, tools};
use object::elf::{SHF_ALLOC, SHT_NOBITS};
use object::read::elf::{ElfFile32, SectionHeader};
use object::{Endianness, Object, ObjectSection};

/// Flash budget for the image's contents, bytes.
pub const FLASH_BUDGET: u64 = 256 * 1024;
/// Static RAM budget (everything but the stack), bytes.
pub const RAM_BUDGET: u64 = 64 * 1024;

/// The firmware package and its board binary.
const PACKAGE: &str = "kerfmeter-firmware";
const BIN: &str = "kerfmeter-firmware";
/// The Cargo profile of the image (root `Cargo.toml`).
const PROFILE: &str = "firmware";

/// `cargo xtask firmware` options.
#[derive(clap::Args)]
pub struct FirmwareArgs {
    /// The chip to build for.
    #[arg(long, value_enum, default_value_t = Chip::C3)]
    pub chip: Chip,
    /// Run clippy (`-D warnings`) on the board binary for that chip instead of building it.
    #[arg(long)]
    pub check: bool,
}

/// A supported chip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Chip {
    /// ESP32-C3 (`riscv32imc-unknown-none-elf`).
    C3,
    /// ESP32-C6 (`riscv32imac-unknown-none-elf`).
    C6,
}

impl Chip {
    /// Every chip, for installing targets.
    pub const ALL: [Chip; 2] = [Chip::C3, Chip::C6];

    /// The chip's name for espflash.
    pub fn espflash_name(self) -> &'static str {
        match self {
            Chip::C3 => "esp32c3",
            Chip::C6 => "esp32c6",
        }
    }

    /// The firmware crate's feature for this chip.
    pub fn feature(self) -> &'static str {
        match self {
            Chip::C3 => "esp32c3",
            Chip::C6 => "esp32c6",
        }
    }

    /// The Rust target triple.
    pub fn target(self) -> &'static str {
        match self {
            Chip::C3 => "riscv32imc-unknown-none-elf",
            Chip::C6 => "riscv32imac-unknown-none-elf",
        }
    }

    /// Whether `address` lies in a window through which the chip's cache maps external flash
    /// (the TRM's memory map).
    fn is_flash_mapped(self, address: u64) -> bool {
        match self {
            // DROM and IROM.
            Chip::C3 => matches!(address, 0x3C00_0000..0x3C80_0000 | 0x4200_0000..0x4280_0000),
            // One window for code and data.
            Chip::C6 => matches!(address, 0x4200_0000..0x4300_0000),
        }
    }
}

impl fmt::Display for Chip {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.feature())
    }
}

/// Flash and RAM use of a built image.
#[derive(Debug, Clone)]
pub struct SizeReport {
    /// The chip it was built for.
    pub chip: Chip,
    /// The ELF that was measured.
    pub elf: PathBuf,
    /// Bytes stored in flash.
    pub flash_bytes: u64,
    /// Bytes of RAM used before the stack.
    pub ram_bytes: u64,
    /// `(section, bytes)` counted as flash.
    pub flash_sections: Vec<(String, u64)>,
    /// `(section, bytes)` counted as static RAM.
    pub ram_sections: Vec<(String, u64)>,
    /// `(section, bytes)` of placeholder sections left out.
    pub placeholders: Vec<(String, u64)>,
}

impl SizeReport {
    /// Whether both figures are within budget.
    pub fn within_budget(&self) -> bool {
        self.flash_bytes <= FLASH_BUDGET && self.ram_bytes <= RAM_BUDGET
    }
}

impl fmt::Display for SizeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fn kib(bytes: u64) -> f64 {
            bytes as f64 / 1024.0
        }
        fn list(sections: &[(String, u64)]) -> String {
            let names: Vec<String> = sections
                .iter()
                .map(|(name, size)| format!("{name} {size}"))
                .collect();
            names.join(", ")
        }
        fn verdict(used: u64, budget: u64) -> &'static str {
            if used <= budget { "ok" } else { "OVER BUDGET" }
        }
        writeln!(f, "firmware {} ({})", self.chip, self.elf.display())?;
        writeln!(
            f,
            "  flash      {:7.1} KiB of {:.0} KiB  {:>5.1}%  {}",
            kib(self.flash_bytes),
            kib(FLASH_BUDGET),
            100.0 * self.flash_bytes as f64 / FLASH_BUDGET as f64,
            verdict(self.flash_bytes, FLASH_BUDGET),
        )?;
        writeln!(
            f,
            "  static RAM {:7.1} KiB of {:.0} KiB  {:>5.1}%  {}",
            kib(self.ram_bytes),
            kib(RAM_BUDGET),
            100.0 * self.ram_bytes as f64 / RAM_BUDGET as f64,
            verdict(self.ram_bytes, RAM_BUDGET),
        )?;
        writeln!(
            f,
            "  flash sections (bytes): {}",
            list(&self.flash_sections)
        )?;
        writeln!(f, "  RAM sections (bytes):   {}", list(&self.ram_sections))?;
        write!(
            f,
            "  not counted (placeholders): {}",
            list(&self.placeholders)
        )
    }
}

/// `cargo xtask firmware`.
pub fn run(args: &FirmwareArgs) -> Result<()> {
    ensure_targets()?;
    if args.check {
        clippy(args.chip)
    } else {
        build(args.chip).map(|_| ())
    }
}

/// Install the chips' Rust targets that are missing.
pub fn ensure_targets() -> Result<()> {
    let output = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .current_dir(root())
        .stderr(Stdio::inherit())
        .output()
        .context("cannot run `rustup target list --installed` (is rustup installed?)")?;
    if !output.status.success() {
        bail!(
            "`rustup target list --installed` failed ({})",
            output.status
        );
    }
    let installed = String::from_utf8_lossy(&output.stdout);
    let missing: Vec<&str> = Chip::ALL
        .iter()
        .map(|chip| chip.target())
        .filter(|target| !installed.lines().any(|line| line.trim() == *target))
        .collect();
    if missing.is_empty() {
        eprintln!(
            "riscv targets installed: {}",
            Chip::ALL.map(Chip::target).join(", ")
        );
        return Ok(());
    }
    eprintln!("installing missing targets: {}", missing.join(", "));
    let mut add = Command::new("rustup");
    add.args(["target", "add"])
        .args(&missing)
        .current_dir(root());
    run_cmd(&mut add)
}

/// Build the image for `chip` with the `firmware` profile, print its size report and fail if it
/// is over budget.
pub fn build(chip: Chip) -> Result<SizeReport> {
    let mut cmd = cargo();
    cmd.args(["build", "--package", PACKAGE, "--bin", BIN])
        .args(["--features", chip.feature()])
        .args(["--target", chip.target()])
        .args(["--profile", PROFILE])
        // Artifacts as JSON on stdout, diagnostics as usual on stderr.
        .arg("--message-format=json-render-diagnostics")
        .stdout(Stdio::piped());
    eprintln!("$ {}", show(&cmd));
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start {}", show(&cmd)))?;
    let mut elf = None;
    let stdout = child.stdout.take().expect("stdout is piped");
    for line in std::io::BufReader::new(stdout).lines() {
        let line = line.context("reading cargo's output")?;
        if let Some(path) = executable_artifact(&line) {
            elf = Some(path);
        }
    }
    let status = child.wait().context("waiting for cargo")?;
    if !status.success() {
        bail!("`{}` failed ({status})", show(&cmd));
    }
    let elf = elf.context("cargo built no executable")?;

    let report = measure(chip, &elf)?;
    println!("{report}");
    if !report.within_budget() {
        bail!(
            "firmware {chip} is over budget (flash ≤ {} KiB, static RAM ≤ {} KiB)",
            FLASH_BUDGET / 1024,
            RAM_BUDGET / 1024
        );
    }
    Ok(report)
}

/// `cargo xtask flash` options: real hardware only.
#[derive(clap::Args)]
pub struct FlashArgs {
    /// The chip on the board.
    #[arg(long, value_enum, default_value_t = Chip::C3)]
    pub chip: Chip,
    /// Serial port of the board (its USB-Serial-JTAG port, e.g. /dev/ttyACM0).
    #[arg(long, env = "KERFMETER_PORT")]
    pub port: String,
    /// Stay attached afterwards and print the board's output.
    #[arg(long)]
    pub monitor: bool,
}

/// espflash is needed to write the image to a board and to turn the ELF into a flash image.
fn ensure_espflash() -> Result<()> {
    let tool = tools::CargoTool {
        name: "espflash",
        crate_name: "espflash",
        install_time: "a few minutes",
    };
    let mut probe = Command::new("espflash");
    probe.arg("--version");
    tools::ensure(&tool, probe)
}

/// Turn the built ELF into the image espflash would write (offline): proves the image is
/// flashable (bootloader app descriptor present, segments valid). Returns the image's path.
pub fn save_image(report: &SizeReport) -> Result<PathBuf> {
    ensure_espflash()?;
    let image = report.elf.with_extension("bin");
    run_cmd(
        Command::new("espflash")
            .args(["save-image", "--chip", report.chip.espflash_name()])
            .arg(&report.elf)
            .arg(&image),
    )?;
    let bytes = std::fs::metadata(&image)
        .with_context(|| format!("reading {}", image.display()))?
        .len();
    println!(
        "flash image {}: {:.1} KiB",
        image.display(),
        bytes as f64 / 1024.0
    );
    Ok(image)
}

/// `cargo xtask flash`: build the image and write it to the board on `--port`.
pub fn flash(args: &FlashArgs) -> Result<()> {
    ensure_targets()?;
    let report = build(args.chip)?;
    ensure_espflash()?;
    let mut cmd = Command::new("espflash");
    cmd.args([
        "flash",
        "--chip",
        args.chip.espflash_name(),
        "--port",
        &args.port,
    ]);
    if args.monitor {
        cmd.arg("--monitor");
    }
    cmd.arg(&report.elf);
    run_cmd(&mut cmd)
}

/// Clippy with `-D warnings` on the firmware crate (library and board binary) for `chip`.
pub fn clippy(chip: Chip) -> Result<()> {
    run_cmd(
        cargo()
            .args(["clippy", "--package", PACKAGE])
            .args(["--features", chip.feature()])
            .args(["--target", chip.target()])
            .args(["--", "-D", "warnings"]),
    )
}

/// Count the flash and static RAM of the ELF at `elf` (see the module docs for the rules).
pub fn measure(chip: Chip, elf: &Path) -> Result<SizeReport> {
    let data = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file = ElfFile32::<Endianness>::parse(&*data)
        .with_context(|| format!("{} is not a 32-bit ELF", elf.display()))?;
    let endian = file.endian();

    let mut report = SizeReport {
        chip,
        elf: elf.to_path_buf(),
        flash_bytes: 0,
        ram_bytes: 0,
        flash_sections: Vec::new(),
        ram_sections: Vec::new(),
        placeholders: Vec::new(),
    };
    for section in file.sections() {
        let header = section.elf_section_header();
        let size = section.size();
        if header.sh_flags(endian) & SHF_ALLOC == 0 || size == 0 {
            continue;
        }
        let name = section.name().unwrap_or("?").to_string();
        if is_placeholder(&name) {
            report.placeholders.push((name, size));
            continue;
        }
        let has_contents = header.sh_type(endian) != SHT_NOBITS;
        let address = section.address();
        let in_flash = chip.is_flash_mapped(address);
        if has_contents {
            report.flash_bytes += size;
            report.flash_sections.push((name.clone(), size));
        }
        if !in_flash {
            report.ram_bytes += size;
            report.ram_sections.push((name, size));
        }
    }
    Ok(report)
}

/// esp-hal's linker sections that reserve address space but hold nothing of the program.
fn is_placeholder(name: &str) -> bool {
    name == ".stack" || name.ends_with("_dummy") || name.ends_with("_gap")
}

/// The `executable` of a `compiler-artifact` message from `cargo --message-format=json`.
fn executable_artifact(line: &str) -> Option<PathBuf> {
    let message: serde_json::Value = serde_json::from_str(line).ok()?;
    if message.get("reason")?.as_str()? != "compiler-artifact" {
        return None;
    }
    message.get("executable")?.as_str().map(PathBuf::from)
}

/// The on-target driver tests (`firmware-esp32/tests/on_target.rs`, embedded-test): built for
/// this chip only.
const ON_TARGET_CHIP: Chip = Chip::C3;
/// Their test target.
const ON_TARGET_TEST: &str = "on_target";
/// The probe-rs runner for them: the C3's built-in USB-Serial-JTAG is the probe.
const ON_TARGET_RUNNER: &str = "probe-rs run --chip esp32c3";

/// `cargo xtask on-target` options: real hardware only.
#[derive(clap::Args)]
pub struct OnTargetArgs {
    /// A board is connected through its USB port (probe-rs uses the C3's built-in USB-JTAG):
    /// flash and run the tests on it. Without this flag nothing runs.
    #[arg(long)]
    pub probe: bool,
}

/// `cargo test` of the on-target tests: the C3 target, the firmware image's profile (esp-hal is
/// meant to be built optimised, and the image's dependencies are reused), defmt logs at `info`.
fn on_target_cargo() -> Command {
    let chip = ON_TARGET_CHIP;
    let mut cmd = cargo();
    cmd.args(["test", "--package", PACKAGE])
        .args(["--features", &format!("{},on-target", chip.feature())])
        .args(["--target", chip.target()])
        .args(["--profile", PROFILE])
        .args(["--test", ON_TARGET_TEST])
        .env("DEFMT_LOG", "info");
    cmd
}

/// Clippy (`-D warnings`) on the on-target driver tests, then build them for the C3 without
/// running them (CI has no board). Only their own test target: the crate's other tests and its
/// unit tests need std (the peripheral fakes) and build on the host only.
pub fn build_on_target_tests() -> Result<()> {
    ensure_targets()?;
    let chip = ON_TARGET_CHIP;
    run_cmd(
        cargo()
            .args(["clippy", "--package", PACKAGE])
            .args(["--features", &format!("{},on-target", chip.feature())])
            .args(["--target", chip.target()])
            .args(["--test", ON_TARGET_TEST])
            .args(["--", "-D", "warnings"]),
    )?;
    run_cmd(on_target_cargo().arg("--no-run"))
}

/// probe-rs flashes and runs the on-target tests.
fn ensure_probe_rs() -> Result<()> {
    let tool = tools::CargoTool {
        name: "probe-rs",
        crate_name: "probe-rs-tools",
        install_time: "about ten minutes",
    };
    let mut probe = Command::new("probe-rs");
    probe.arg("--version");
    tools::ensure(&tool, probe)
}

/// Run the on-target driver tests on a board through probe-rs (`probe: true`); without a board
/// (`probe: false`, or no probe found) fail, saying why: nothing is simulated.
pub fn run_on_target_tests(probe: bool) -> Result<()> {
    if !probe {
        bail!(
            "the on-target tests run on a real board only: connect the ESP32-C3 board's USB port \
             (wired as docs/hardware.md's wiring table says, no gauge on the hub, motor supply on) and \
             pass --probe; nothing was run"
        );
    }
    ensure_targets()?;
    ensure_probe_rs()?;
    let list = Command::new("probe-rs")
        .arg("list")
        .output()
        .context("cannot run `probe-rs list`")?;
    let probes = String::from_utf8_lossy(&list.stdout);
    if !list.status.success() || probes.contains("No debug probes were found") {
        bail!(
            "no debug probe found (`probe-rs list`: {}): connect the board's USB port (the C3's \
             built-in USB-JTAG); on Linux, install probe-rs's udev rules",
            probes.trim()
        );
    }
    eprintln!("{}", probes.trim());
    let runner_var = format!(
        "CARGO_TARGET_{}_RUNNER",
        ON_TARGET_CHIP.target().to_uppercase().replace('-', "_")
    );
    run_cmd(on_target_cargo().env(runner_var, ON_TARGET_RUNNER))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_are_recognised() {
        for name in [".stack", ".rwdata_dummy", ".rotext_dummy", ".text_gap"] {
            assert!(is_placeholder(name), "{name}");
        }
        for name in [
            ".text",
            ".rodata",
            ".rwtext",
            ".rwtext.wifi",
            ".data",
            ".bss",
            ".trap",
        ] {
            assert!(!is_placeholder(name), "{name}");
        }
    }

    #[test]
    fn the_executable_is_found_in_cargo_json() {
        let line = r#"{"reason":"compiler-artifact","executable":"/t/fw","target":{}}"#;
        assert_eq!(executable_artifact(line), Some(PathBuf::from("/t/fw")));
        let lib = r#"{"reason":"compiler-artifact","executable":null}"#;
        assert_eq!(executable_artifact(lib), None);
        assert_eq!(executable_artifact("not json"), None);
    }
}
