//! The torque–angle curve of a run, as PNG or SVG (by the file's extension), with the jam point
//! marked: what the device pushed, and where the inset stopped.

use std::path::Path;

use kerfmeter_protocol::KerfResult;
use plotters::prelude::*;

use kerfmeter::{Curve, Error, Result};

/// Picture size, pixels.
const SIZE: (u32, u32) = (1000, 650);

/// The output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    /// Raster.
    Png,
    /// Vector.
    Svg,
}

impl PlotFormat {
    /// The format for `path`'s extension.
    pub fn for_path(path: &Path) -> Result<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(Self::Png),
            Some("svg") => Ok(Self::Svg),
            _ => Err(Error::invalid(format!(
                "plot file {} must end in .png or .svg",
                path.display()
            ))),
        }
    }
}

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // DejaVu Sans, shipped by the `dejavu` crate: no system fonts needed.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// Draw `curve` (and the jam of `result`) into `path`, written atomically.
pub fn plot_curve(curve: &Curve, result: Option<&KerfResult>, path: &Path) -> Result<()> {
    let format = PlotFormat::for_path(path)?;
    if curve.samples.is_empty() {
        return Err(Error::invalid(
            "there is no curve to plot: run a measurement first",
        ));
    }
    register_font();
    let bytes = match format {
        PlotFormat::Png => png_bytes(curve, result),
        PlotFormat::Svg => svg_bytes(curve, result),
    }
    .map_err(|message| Error::File {
        path: path.to_owned(),
        message: format!("cannot draw the plot: {message}"),
    })?;
    kerfmeter::files::write_atomically(path, &bytes)
}

/// The plot as a PNG, drawn in memory and encoded with the `png` crate, carrying this tool's
/// marker (a `tEXt` chunk before the pixels: see [`kerfmeter_plan::ownership::PLOT_MARKER`]).
fn png_bytes(curve: &Curve, result: Option<&KerfResult>) -> std::result::Result<Vec<u8>, String> {
    let (width, height) = SIZE;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    draw(
        BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(),
        curve,
        result,
    )?;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let encoded = encoder
        .add_text_chunk(
            "Software".into(),
            kerfmeter_plan::ownership::plot_marker_text(),
        )
        .and_then(|()| encoder.write_header())
        .and_then(|mut writer| writer.write_image_data(&rgb));
    encoded.map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// The plot as SVG, drawn in memory, with this tool's marker as a comment after the root's
/// opening tag.
fn svg_bytes(curve: &Curve, result: Option<&KerfResult>) -> std::result::Result<Vec<u8>, String> {
    let mut text = String::new();
    draw(
        SVGBackend::with_string(&mut text, SIZE).into_drawing_area(),
        curve,
        result,
    )?;
    let comment = format!(
        "\n<!-- {} -->",
        kerfmeter_plan::ownership::plot_marker_text()
    );
    match text
        .find("<svg")
        .and_then(|at| text[at..].find('>').map(|end| at + end + 1))
    {
        Some(after_root) => text.insert_str(after_root, &comment),
        None => return Err("the SVG backend wrote no <svg> element".into()),
    }
    Ok(text.into_bytes())
}

/// The axis range that holds every value: from 0, or below it when a value is negative (the
/// back-off's torque, a hub that turned back past zero), to the largest value or at least
/// `least`; widened by `margin` of its length at each end that holds values.
fn span(values: impl Iterator<Item = f32>, least: f32, margin: f32) -> std::ops::Range<f32> {
    let (lo, hi) = values.fold((0.0f32, least), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let pad = (hi - lo) * margin;
    let lo = if lo < 0.0 { lo - pad } else { 0.0 };
    lo..hi + pad
}

fn draw<DB: DrawingBackend>(
    area: DrawingArea<DB, plotters::coord::Shift>,
    curve: &Curve,
    result: Option<&KerfResult>,
) -> std::result::Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    area.fill(&WHITE).map_err(e)?;
    // The jam's marker is inside the axes too.
    let jam = result.map(|r| (r.angle_deg, r.torque_at_jam_nm));
    let points = || {
        curve
            .samples
            .iter()
            .map(|s| (s.angle_deg, s.torque_nm))
            .chain(jam)
    };
    let angles = span(points().map(|(angle, _)| angle), 1.0, 0.05);
    let torques = span(points().map(|(_, torque)| torque), 0.05, 0.1);
    let title = match result {
        Some(r) => format!(
            "Run {}: kerf {:.1} µm at {:.1} N",
            r.run_id, r.kerf_um, r.force_at_jam_n
        ),
        None => format!("Run {}", curve.run_id),
    };
    let mut chart = ChartBuilder::on(&area)
        .caption(title, ("sans-serif", 28))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(angles, torques)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("hub angle (°)")
        .y_desc("commanded torque (N·m)")
        .label_style(("sans-serif", 18))
        .draw()
        .map_err(e)?;
    chart
        .draw_series(LineSeries::new(
            curve.samples.iter().map(|s| (s.angle_deg, s.torque_nm)),
            BLUE.stroke_width(2),
        ))
        .map_err(e)?
        .label("torque vs. angle")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    if let Some(r) = result {
        chart
            .draw_series(std::iter::once(Circle::new(
                (r.angle_deg, r.torque_at_jam_nm),
                7,
                RED.filled(),
            )))
            .map_err(e)?
            .label(format!(
                "jam: {:.2}°, {:.3} N·m",
                r.angle_deg, r.torque_at_jam_nm
            ))
            .legend(|(x, y)| Circle::new((x + 10, y), 6, RED.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 18))
        .draw()
        .map_err(e)?;
    area.present().map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axis_holds_negative_values_and_starts_at_zero_otherwise() {
        assert_eq!(span([0.5, 10.0].into_iter(), 1.0, 0.1), 0.0..11.0);
        // A hub that turned back past zero: the axis reaches below it, with the margin.
        let r = span([-1.0, 9.0].into_iter(), 1.0, 0.1);
        assert!(
            (r.start + 2.0).abs() < 1e-6 && (r.end - 10.0).abs() < 1e-6,
            "{r:?}"
        );
        // Nothing drawn yet still gives an axis of some length.
        assert_eq!(span(std::iter::empty(), 0.05, 0.1), 0.0..0.055);
    }
}
