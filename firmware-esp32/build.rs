//! Link arguments for the chip build only: host builds of the library stay plain.

fn main() {
    let chip = std::env::var_os("CARGO_FEATURE_BOARD").is_some();
    let target = std::env::var("TARGET").unwrap_or_default();
    if chip && target.starts_with("riscv32") {
        // esp-hal's memory layout and runtime; without it: `undefined symbol: _stack_start`.
        println!("cargo:rustc-link-arg-bins=-Tlinkall.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
