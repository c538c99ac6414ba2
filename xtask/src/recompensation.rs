//! The recompensation step of `cargo xtask test`: boxes.py's own plans, recompensated by the
//! `kerfmeter` binary, against the same generators' uncompensated plans dilated
//! (`host-lib/plan/tests/plan_recompensation_boxes.rs`, issue 32 §4).
//!
//! boxes.py is not on PyPI (the `boxes` there is another project), so CI cannot install it: the
//! step runs on a fixed sample of its plans kept in `host-lib/plan/tests/boxes_plans/` (made by
//! `host-lib/plan/tests/boxes_plans.py` from boxes.py at commit 7d1a89d9). Every generator is
//! compared by making all their plans with a boxes.py checkout and pointing the same test at them:
//!
//! ```sh
//! python host-lib/plan/tests/boxes_plans.py BOXES_CHECKOUT /tmp/boxes-plans
//! KERFMETER_BOXES_PLANS=/tmp/boxes-plans cargo test -p kerfmeter-plan \
//!     --test plan_recompensation_boxes -- --ignored --nocapture
//! ```

use anyhow::Result;

use crate::{cargo, root, run_cmd};

/// Build the CLI and compare the sample's recompensations (the test prints one line a generator).
pub fn test() -> Result<()> {
    crate::build_cli(false)?;
    let kerfmeter = root().join("target").join("debug").join("kerfmeter");
    run_cmd(
        cargo()
            .args([
                "test",
                "-p",
                "kerfmeter-plan",
                "--test",
                "plan_recompensation_boxes",
            ])
            .args(["--", "--ignored", "--nocapture"])
            .env("KERFMETER", kerfmeter)
            .env_remove("KERFMETER_BOXES_PLANS"),
    )
}
