//! `cargo xtask bench-plan`: the whole `kerfmeter dilate` command on generated plans of growing
//! size, as a user runs it, beside the dilation kernel's share and GEOS buffering the same parts.
//!
//! For each size (156, 625 and 2,500 box-joint parts by default, each 4× the one before: 624 to
//! 10,000 closed contours)
//! the plan example `plan_bench` (in `kerfmeter-plan`) writes the plan as SVG, DXF and WKT. Then,
//! per format and size:
//!
//! * **command**: the release `kerfmeter dilate plan.svg --kerf-um 150 -o out.svg`, end to end
//!   (start, read, dilate, write the file, exit); the median of `--runs` runs, wall time and CPU
//!   time (all threads; on a shared machine the wall time also says how busy it is, so the
//!   load average is printed with each table);
//! * **kernel**: the same plan dilated in one process (`plan_bench phases`), split into reading,
//!   the kernel (nesting, offsets, checks) and writing, from the stages the library reports;
//! * **peak memory**: the command's largest resident set (`ru_maxrss` of the child from `wait4`),
//!   and its ratio to the input file's size;
//! * **growth**: how much longer the command took than on the size before, beside how many times
//!   the parts (the target: 4× the parts never more than 5× the time);
//! * **GEOS**: shapely buffering the same parts (polygons with holes, arcs flattened) by the same
//!   half kerf, when the Python given by `--python` has shapely; otherwise "unavailable".
//!
//! After each table the issue's targets are judged on it (met, or by how much not): the largest
//! plan's command within GEOS's time on the same parts, every 4× the parts at most 5× the time,
//! and the largest plan's peak memory under 10× its file (the small plans' peaks are the
//! process's fixed ~9 MB). Judged, not enforced: wall times on a shared two-core machine vary
//! by tens of per cent from run to run, so the command exits 0 either way.
//!
//! This is a benchmark, not a test: `cargo xtask test` does not run it.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use crate::{cargo, root, run_cmd};

/// The kerf the plans are dilated by, µm.
const KERF_UM: f64 = 150.0;

/// `cargo xtask bench-plan` options.
#[derive(clap::Args)]
pub struct BenchPlanArgs {
    /// Plan sizes, in parts (each part is 4 contours).
    #[arg(long, value_delimiter = ',', default_values_t = [156, 625, 2500])]
    pub parts: Vec<usize>,
    /// Runs of the command per plan (the median is shown).
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// The Python to time GEOS (shapely) with.
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Time this `kerfmeter` binary instead of building the workspace's (e.g. an older build, for
    /// before-and-after figures; the phases are always the workspace's).
    #[arg(long, value_name = "PATH")]
    pub kerfmeter: Option<PathBuf>,
}

/// One run of a child process: its wall time, CPU time (user + system, all threads) and peak
/// resident set.
struct Run {
    time: Duration,
    cpu_s: f64,
    max_rss_bytes: u64,
}

/// Run `cmd` (its output discarded) and measure it; fails when it fails.
fn measure(cmd: &mut Command) -> Result<Run> {
    let start = Instant::now();
    let child = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("cannot start the command")?;
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero `rusage` is valid; wait4 fills it for our own child, which it reaps.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let got = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    let time = start.elapsed();
    if got != pid {
        bail!("wait4 failed: {}", std::io::Error::last_os_error());
    }
    if !libc::WIFEXITED(status) || libc::WEXITSTATUS(status) != 0 {
        let mut err = String::new();
        if let Some(mut e) = child.stderr {
            use std::io::Read;
            e.read_to_string(&mut err).ok();
        }
        bail!("the command failed (wait status {status}): {err}");
    }
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    Ok(Run {
        time,
        cpu_s: secs(usage.ru_utime) + secs(usage.ru_stime),
        // Linux gives ru_maxrss in KiB.
        max_rss_bytes: usage.ru_maxrss as u64 * 1024,
    })
}

/// The in-process split of one dilation (seconds): reading, kernel, writing.
struct Phases {
    read_s: f64,
    kernel_s: f64,
    write_s: f64,
}

fn phases(example: &Path, plan: &Path) -> Result<Phases> {
    let out = Command::new(example)
        .arg("phases")
        .arg(plan)
        .args(["--kerf-um", &KERF_UM.to_string()])
        .output()
        .context("cannot run plan_bench phases")?;
    if !out.status.success() {
        bail!(
            "plan_bench phases failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let f = |k: &str| v[k].as_f64().with_context(|| format!("no {k} in {v}"));
    Ok(Phases {
        read_s: f("read_s")?,
        kernel_s: f("kernel_s")?,
        write_s: f("write_s")?,
    })
}

/// Seconds GEOS takes to buffer the parts of a WKT file (the best of three), or why not.
fn geos(python: &str, wkt: &Path) -> std::result::Result<f64, String> {
    const SCRIPT: &str = r#"
import sys, time, shapely
geoms = shapely.from_wkt(open(sys.argv[1]).read().split("\n")[:-1])
best = float("inf")
for _ in range(3):
    t = time.perf_counter()
    shapely.buffer(geoms, float(sys.argv[2]), quad_segs=8)
    best = min(best, time.perf_counter() - t)
print(best)
"#;
    let out = Command::new(python)
        .args(["-c", SCRIPT])
        .arg(wkt)
        .arg((KERF_UM / 2000.0).to_string())
        .output()
        .map_err(|e| format!("unavailable ({python}: {e})"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(if err.contains("No module named 'shapely'") {
            format!("unavailable (no shapely in {python})")
        } else {
            format!("failed: {}", err.trim())
        });
    }
    String::from_utf8_lossy(&out.stdout)
        .trim()
        .parse()
        .map_err(|e| format!("failed: {e}"))
}

/// Build the release binary and the example; their paths.
fn build() -> Result<(PathBuf, PathBuf)> {
    crate::build_cli(true)?;
    run_cmd(cargo().args([
        "build",
        "--release",
        "-p",
        "kerfmeter-plan",
        "--example",
        "plan_bench",
    ]))?;
    let release = root().join("target").join("release");
    Ok((
        release.join("kerfmeter"),
        release.join("examples").join("plan_bench"),
    ))
}

/// One row of the table.
struct Row {
    parts: usize,
    file_bytes: u64,
    command: Run,
    phases: Phases,
    geos: std::result::Result<f64, String>,
}

pub fn run(args: &BenchPlanArgs) -> Result<()> {
    if args.runs == 0 || args.parts.is_empty() {
        bail!("--runs and --parts must not be empty");
    }
    let mut sizes = args.parts.clone();
    sizes.sort_unstable();
    sizes.dedup();
    if sizes.contains(&0) {
        bail!("--parts: a plan needs at least one part");
    }
    let (built, example) = build()?;
    let cli = args.kerfmeter.clone().unwrap_or(built);
    let dir = root().join("target").join("bench-plan");
    for &parts in &sizes {
        let status = Command::new(&example)
            .args(["generate", "--parts", &parts.to_string(), "--out-dir"])
            .arg(&dir)
            .status()?;
        if !status.success() {
            bail!("plan_bench generate --parts {parts} failed");
        }
    }
    for format in ["svg", "dxf"] {
        let mut rows = Vec::new();
        for &parts in &sizes {
            let plan = dir.join(format!("plan-{parts}.{format}"));
            let out = dir.join(format!("out-{parts}.{format}"));
            let mut runs = Vec::new();
            for _ in 0..args.runs {
                runs.push(measure(
                    Command::new(&cli)
                        .arg("dilate")
                        .arg(&plan)
                        .args(["--kerf-um", &KERF_UM.to_string(), "-o"])
                        .arg(&out),
                )?);
            }
            runs.sort_by_key(|r| r.time);
            let peak = runs.iter().map(|r| r.max_rss_bytes).max().unwrap_or(0);
            let mut command = runs.swap_remove(runs.len() / 2);
            command.max_rss_bytes = peak;
            rows.push(Row {
                parts,
                file_bytes: std::fs::metadata(&plan)?.len(),
                command,
                phases: phases(&example, &plan)?,
                geos: geos(&args.python, &dir.join(format!("plan-{parts}.wkt"))),
            });
        }
        print_table(format, &rows, args.runs);
        print_targets(&rows);
    }
    Ok(())
}

/// Growth of the command's time per step of sizes: (time ratio, parts ratio).
fn growths(rows: &[Row]) -> Vec<(f64, f64)> {
    rows.windows(2)
        .map(|w| {
            let time = w[1].command.time.as_secs_f64() / w[0].command.time.as_secs_f64();
            (time, w[1].parts as f64 / w[0].parts as f64)
        })
        .collect()
}

/// The issue's three targets, judged on these rows.
fn print_targets(rows: &[Row]) {
    let Some(largest) = rows.last() else { return };
    let verdict = |met: bool| if met { "met" } else { "NOT met" };
    let command_s = largest.command.time.as_secs_f64();
    let time = match &largest.geos {
        Ok(geos_s) => format!(
            "{}: {command_s:.3} s against GEOS's {geos_s:.3} s ({:.2}×)",
            verdict(command_s <= *geos_s),
            command_s / geos_s
        ),
        Err(why) => format!("not judged: GEOS {why}"),
    };
    // Each step's time ratio taken to 4× the parts (t^(ln 4 / ln p)): the sizes may grow by
    // other factors than 4.
    let worst_per_4x = growths(rows)
        .into_iter()
        .map(|(time, parts)| time.powf(4f64.ln() / parts.ln()))
        .reduce(f64::max);
    let growth = match worst_per_4x {
        Some(worst) => format!("{}: at most {worst:.2}× per 4×", verdict(worst <= 5.0)),
        None => "not judged: one size only".to_owned(),
    };
    let ratio = largest.command.max_rss_bytes as f64 / largest.file_bytes as f64;
    println!("targets at {} contours:", 4 * largest.parts);
    println!("  the whole command within GEOS's time: {time}");
    println!("  4× the parts at most 5× the time: {growth}");
    println!(
        "  peak memory under 10× the file: {}: {ratio:.1}×",
        verdict(ratio < 10.0)
    );
}

fn print_table(format: &str, rows: &[Row], runs: usize) {
    println!(
        "\n{} plans: `kerfmeter dilate plan.{format} --kerf-um {KERF_UM} -o out.{format}` (release, median of {runs}), beside its phases in one process and GEOS",
        format.to_uppercase()
    );
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "load average (1, 5, 15 min): {}",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "{:>6} {:>8} {:>9} {:>10} {:>7} {:>12} {:>9} {:>9} {:>9} {:>10} {:>8} {:>10}",
        "parts",
        "contours",
        "file MB",
        "command s",
        "cpu s",
        "growth",
        "read s",
        "kernel s",
        "write s",
        "peak MB",
        "peak/file",
        "GEOS s"
    );
    let mut before: Option<(f64, usize)> = None;
    for r in rows {
        let t = r.command.time.as_secs_f64();
        let growth = before.map_or("".into(), |(bt, bp)| {
            format!("{:.2}× /{:.1}×", t / bt, r.parts as f64 / bp as f64)
        });
        before = Some((t, r.parts));
        let geos = match &r.geos {
            Ok(s) => format!("{s:.3}"),
            Err(why) => why.clone(),
        };
        println!(
            "{:>6} {:>8} {:>9.2} {:>10.3} {:>7.3} {:>12} {:>9.3} {:>9.3} {:>9.3} {:>10.1} {:>8.1}× {:>10}",
            r.parts,
            4 * r.parts,
            r.file_bytes as f64 / 1e6,
            t,
            r.command.cpu_s,
            growth,
            r.phases.read_s,
            r.phases.kernel_s,
            r.phases.write_s,
            r.command.max_rss_bytes as f64 / 1e6,
            r.command.max_rss_bytes as f64 / r.file_bytes as f64,
            geos
        );
    }
}
