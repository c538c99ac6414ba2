//! `--seeds`: the sweep once per seed, each seed's figures on a row and every reading of all of
//! them pooled. It is how the firmware's checks are judged on seeds they were not developed on
//! (docs/twin.md, "Seeds developed on and held out").

use kerfmeter_protocol::QualityFlags;
use kerfmeter_twin::study::robustness::{
    Class, DrawReport, ErrorStats, Summary, Sweep, classify, run_draw,
};
use kerfmeter_twin::study::{Outcome, parallel_map};
use serde_json::{Value, json};

use super::{Args, error_line, stats_json};

/// Seeds given as `FIRST-LAST` or `A,B,C` (or both: `1-3,9`).
#[derive(Clone, Debug)]
pub struct SeedList(pub Vec<u64>);

/// Parse `--seeds`.
pub fn seed_list(text: &str) -> Result<SeedList, String> {
    let mut seeds = Vec::new();
    for part in text.split(',').map(str::trim) {
        let number = |s: &str| {
            s.trim()
                .parse::<u64>()
                .map_err(|_| format!("`{s}` in `{text}` is not a seed (a whole number)"))
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (number(a)?, number(b)?);
                if b < a || b - a >= 10_000 {
                    return Err(format!(
                        "`{part}`: a range goes up, by fewer than 10000 seeds"
                    ));
                }
                seeds.extend(a..=b);
            }
            None => seeds.push(number(part)?),
        }
    }
    Ok(SeedList(seeds))
}

/// One seed's figures.
struct SeedRow {
    seed: u64,
    summary: Summary,
    /// Readings within the tolerance that a flag distrusts anyway.
    flagged_correct: usize,
}

/// Readings within `tolerance_um` that a flag distrusts.
fn flagged_correct(reports: &[DrawReport], tolerance_um: f64) -> usize {
    reports
        .iter()
        .filter(|r| {
            classify(&r.outcome, tolerance_um) == Class::Flagged
                && r.outcome
                    .error_um()
                    .is_some_and(|e| e.abs() <= tolerance_um)
        })
        .count()
}

/// Run `make(seed)`'s sweep for every seed; print a row per seed and the pooled figures.
/// Whether every draw ended properly (and, with `--strict`, no reading was unflagged wrong).
pub fn run_seeds(args: &Args, seeds: &[u64], make: &dyn Fn(u64) -> Sweep) -> bool {
    let mut rows = Vec::new();
    let mut pooled: Vec<DrawReport> = Vec::new();
    for &seed in seeds {
        let sweep = make(seed);
        let reports = parallel_map(
            args.draws,
            args.threads,
            &|index| run_draw(&sweep.draw(index)),
            &|_| {},
        );
        let row = SeedRow {
            seed,
            summary: Summary::of(&reports, args.tolerance_um),
            flagged_correct: flagged_correct(&reports, args.tolerance_um),
        };
        if !args.json {
            print_row(&row);
        }
        rows.push(row);
        pooled.extend(reports);
    }
    let all = SeedRow {
        seed: 0,
        summary: Summary::of(&pooled, args.tolerance_um),
        flagged_correct: flagged_correct(&pooled, args.tolerance_um),
    };
    if args.json {
        println!("{}", seeds_json(args, &rows, &all));
    } else {
        print_pooled(args, seeds, &all, &pooled);
    }
    let wrong = rows
        .iter()
        .any(|r| !r.summary.of_class(Class::UnflaggedWrong).is_empty());
    rows.iter().all(|r| r.summary.all_ended_safely()) && !(args.strict && wrong)
}

fn print_row(row: &SeedRow) {
    let s = &row.summary;
    let u = &s.unflagged_readings;
    let errors = if u.n == 0 {
        "none".to_owned()
    } else {
        format!("p95 |e| {:.2} µm, max {:.2} µm", u.p95_abs_um, u.max_abs_um)
    };
    println!(
        "seed {:>6}: {:>3} readings, {:>3} unflagged ({errors}), {} correct but flagged, unflagged wrong: {:?}",
        row.seed,
        s.readings(),
        u.n,
        row.flagged_correct,
        s.of_class(Class::UnflaggedWrong),
    );
}

/// The errors of the unflagged readings with an advisory `flag`, and of those without it.
fn unflagged_split(
    reports: &[DrawReport],
    tolerance_um: f64,
    flag: QualityFlags,
) -> (ErrorStats, ErrorStats) {
    let (mut with, mut without) = (Vec::new(), Vec::new());
    for r in reports {
        if let Outcome::Reading { result, .. } = &r.outcome
            && classify(&r.outcome, tolerance_um) != Class::Flagged
            && let Some(error_um) = r.outcome.error_um()
        {
            if result.flags.contains(flag) {
                with.push(error_um);
            } else {
                without.push(error_um);
            }
        }
    }
    (ErrorStats::of(&with), ErrorStats::of(&without))
}

fn print_pooled(args: &Args, seeds: &[u64], all: &SeedRow, pooled: &[DrawReport]) {
    let s = &all.summary;
    println!(
        "pooled over {} seeds × {} draws: {} readings",
        seeds.len(),
        args.draws,
        s.readings()
    );
    println!("  {}", error_line("every reading", &s.all_readings));
    println!(
        "  {}",
        error_line("unflagged readings", &s.unflagged_readings)
    );
    println!(
        "  unflagged wrong (off by more than {} µm): {}; correct but flagged: {}",
        args.tolerance_um,
        s.of_class(Class::UnflaggedWrong).len(),
        all.flagged_correct
    );
    let (with, without) = unflagged_split(pooled, args.tolerance_um, QualityFlags::PLAY_MODELLED);
    println!("  {}", error_line("unflagged, play-modelled", &with));
    println!("  {}", error_line("unflagged, not play-modelled", &without));
    println!(
        "  every draw ended in a reading or a typed fault or refusal, motor safe: {}",
        if s.all_ended_safely() { "yes" } else { "NO" }
    );
    println!("  replay a draw: cargo xtask robustness --seed S --replay D [--ablate]");
}

fn row_json(row: &SeedRow) -> Value {
    json!({
        "seed": row.seed,
        "readings": row.summary.readings(),
        "error_all_readings": stats_json(&row.summary.all_readings),
        "error_unflagged_readings": stats_json(&row.summary.unflagged_readings),
        "unflagged_wrong": row.summary.of_class(Class::UnflaggedWrong),
        "flagged_correct": row.flagged_correct,
        "all_ended_safely": row.summary.all_ended_safely(),
    })
}

fn seeds_json(args: &Args, rows: &[SeedRow], all: &SeedRow) -> Value {
    let mut pooled = row_json(all);
    if let Some(map) = pooled.as_object_mut() {
        map.remove("seed");
        map.insert(
            "unflagged_wrong".into(),
            json!(all.summary.of_class(Class::UnflaggedWrong).len()),
        );
    }
    json!({
        "draws_per_seed": args.draws,
        "tolerance_um": args.tolerance_um,
        "force_n": args.force_n,
        "seeds": rows.iter().map(row_json).collect::<Vec<_>>(),
        "pooled": pooled,
    })
}
