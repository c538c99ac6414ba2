//! Fuzz the plan readers: any bytes, given to the SVG reader (when they are UTF-8) and to the DXF
//! reader, as `kerfmeter dilate` would with `--units mm` (so that unitless inputs reach the
//! geometry too), dilated by 150 µm.
//!
//! Property: no panic. Every input is read, dilated and written, or refused with an error.
//! Seeded from the plan crate's corpus (`fuzz/seeds/plan_readers/`, copies of
//! `host-lib/plan/tests/corpus/`).

#![no_main]

use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::dxf_plan::{DxfOptions, dilate_dxf};
use kerfmeter_plan::outcome::AssumedUnits;
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let kerf = KerfSource::Uniform(150.0);
    if let Ok(text) = std::str::from_utf8(data) {
        let opts = SvgOptions {
            assume_units: Some(AssumedUnits::Mm),
            ..SvgOptions::default()
        };
        let _ = dilate_svg(text, &kerf, &opts);
    }
    let opts = DxfOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..DxfOptions::default()
    };
    let _ = dilate_dxf(data, &kerf, &opts);
});
