//! Link arguments for the chip builds only: host builds of the library stay plain.
//!
//! - The board binary (a chip feature): esp-hal's memory layout and runtime.
//! - The on-target tests (feature `on-target`, `tests/on_target.rs`): the same, plus embedded-test's
//!   table of test cases and defmt's sections (probe-rs reads both from the ELF).

fn main() {
    let chip = std::env::var_os("CARGO_FEATURE_BOARD").is_some();
    let on_target = std::env::var_os("CARGO_FEATURE_ON_TARGET").is_some();
    let target = std::env::var("TARGET").unwrap_or_default();
    let riscv = target.starts_with("riscv32");
    if chip && riscv {
        // esp-hal's memory layout and runtime; without it: `undefined symbol: _stack_start`.
        println!("cargo:rustc-link-arg-bins=-Tlinkall.x");
    }
    if on_target && riscv {
        println!("cargo:rustc-link-arg-tests=-Tlinkall.x");
        println!("cargo:rustc-link-arg-tests=-Tembedded-test.x");
        println!("cargo:rustc-link-arg-tests=-Tdefmt.x");
    }
    // embedded-test's macros mark test functions with `cfg_attr(rust_analyzer, test)`.
    println!("cargo::rustc-check-cfg=cfg(rust_analyzer)");
    println!("cargo:rerun-if-changed=build.rs");
}
