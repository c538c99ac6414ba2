//! `cargo xtask wiring`: the wiring drawing (`docs/wiring.svg`), generated from the firmware's own
//! pin table so that it cannot drift from it.
//!
//! The table is `kerfmeter_firmware::board::wiring`: the ESP32-C3's GPIO for each signal (the
//! same names `take_pins!` moves out of esp-hal's peripherals), the part and pin at the other end,
//! the components the board must carry on the wire, and the power connections. Nothing here knows
//! a pin number. `--check` writes nothing and fails when the committed drawing is not what the
//! table gives now; `cargo xtask test` runs it.
//!
//! The SVG is written with xml-rs's `EventWriter` (already in the tree through `dxf`), which
//! escapes text and attributes; the layout is a fixed grid, so the output is byte-for-byte the
//! same for the same table.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use kerfmeter_firmware::board::wiring::{
    self, Direction, Fitted, Gpios, POWER, Part, PowerWire, WIRES, Wire,
};
use xml::writer::{EmitterConfig, EventWriter, XmlEvent};

/// `cargo xtask wiring` options.
#[derive(clap::Args)]
pub struct WiringArgs {
    /// Write nothing; fail when the drawing differs from what the pin table gives.
    #[arg(long)]
    pub check: bool,
    /// The drawing's path (default: docs/wiring.svg in the workspace).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The committed drawing, relative to the workspace root.
pub const DRAWING: &str = "docs/wiring.svg";

/// Write the drawing, or with `--check` compare it.
pub fn run(args: &WiringArgs) -> Result<()> {
    let path = args
        .out
        .clone()
        .unwrap_or_else(|| crate::root().join(DRAWING));
    let svg = drawing(&wiring::ESP32C3)?;
    if args.check {
        check(&path, &svg)
    } else {
        std::fs::write(&path, &svg).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {} from the firmware's pin table", path.display());
        Ok(())
    }
}

/// The step of `cargo xtask test`: the committed drawing is current.
pub fn check_committed() -> Result<()> {
    check(&crate::root().join(DRAWING), &drawing(&wiring::ESP32C3)?)
}

fn check(path: &Path, svg: &str) -> Result<()> {
    let committed = std::fs::read_to_string(path)
        .with_context(|| format!("reading {} (run `cargo xtask wiring`)", path.display()))?;
    // A checkout that turned the line ends into CRLF holds the same drawing.
    let committed = committed.replace("\r\n", "\n");
    if committed != svg {
        let first_difference = committed
            .lines()
            .chain(std::iter::repeat(""))
            .zip(svg.lines().chain(std::iter::repeat("")))
            .take(committed.lines().count().max(svg.lines().count()))
            .enumerate()
            .find(|(_, (was, is))| was != is);
        let difference = match first_difference {
            Some((line, (was, is))) => format!(
                "line {}: committed `{}`, the table gives `{}`",
                line + 1,
                was.trim(),
                is.trim()
            ),
            None => "only the line ends differ".to_string(),
        };
        bail!(
            "{} is not what the firmware's pin table (firmware-esp32/src/board/wiring.rs) gives: \
             run `cargo xtask wiring` and commit the drawing ({difference})",
            path.display()
        );
    }
    eprintln!("{} matches the firmware's pin table", path.display());
    Ok(())
}

// Layout, px.
const WIDTH: u32 = 1240;
const MCU_X: u32 = 20;
const MCU_RIGHT: u32 = 200;
const PART_X: u32 = 780;
const PART_RIGHT: u32 = 940;
const SIDE_X: u32 = 1030;
const SIDE_RIGHT: u32 = 1210;
const ROW_H: u32 = 44;
const TOP: u32 = 96;
/// Space above a group's first row for the part's name.
const GROUP_HEAD: u32 = 40;
const GROUP_GAP: u32 = 30;

const OUT_COLOUR: &str = "#1f5fbf";
const IN_COLOUR: &str = "#1e8a3a";
const ANALOG_COLOUR: &str = "#c05a00";
const POWER_COLOUR: &str = "#c01f1f";
const GROUND_COLOUR: &str = "#333333";
const MOTOR_COLOUR: &str = "#7a3fa0";

/// One line between the MCU and a part, as drawn.
struct Row {
    mcu_pin: String,
    part_pin: &'static str,
    over: String,
    under: String,
    colour: &'static str,
}

/// The SVG text of the wiring for `gpios`.
pub fn drawing(gpios: &Gpios) -> Result<String> {
    let groups = [Part::G2, Part::As5048a].map(|part| (part, rows(gpios, part)));
    let mut svg = Svg::new()?;
    let rows_total: u32 = groups.iter().map(|(_, r)| r.len() as u32).sum();
    let body_bottom =
        TOP + groups.len() as u32 * (GROUP_HEAD + GROUP_GAP) + rows_total * ROW_H - GROUP_GAP;
    // The power list's heading, its lines and the USB line, the legend.
    let height = body_bottom + 34 + 18 * (POWER.len() as u32 + 1) + 30 + 16;
    svg.open(
        "svg",
        &[
            ("width", WIDTH.to_string()),
            ("height", height.to_string()),
            ("viewBox", format!("0 0 {WIDTH} {height}")),
            ("font-family", "sans-serif".into()),
        ],
    )?;
    svg.comment(
        " Generated by `cargo xtask wiring` from firmware-esp32/src/board/wiring.rs: do not edit \
         (its check mode, a step of `cargo xtask test`, fails when this is stale). ",
    )?;
    svg.rect(0, 0, WIDTH, height, "#ffffff", "none")?;
    svg.text(
        MCU_X,
        32,
        &format!("Kerfmeter wiring: {} board", chip_name(gpios)),
        &[("font-size", "20"), ("font-weight", "bold")],
    )?;
    svg.text(
        MCU_X,
        54,
        "Generated from the firmware's pin table (firmware-esp32/src/board/wiring.rs) by \
         `cargo xtask wiring`. Each wire: the MCU's pin, the part's pin, what to fit on it.",
        &[("font-size", "12")],
    )?;
    svg.text(
        MCU_X,
        72,
        "The AS5048A runs at 3.3 V with VDD5V tied to VDD3V3. Nothing here is 5 V: the C3's \
         pins are not 5 V tolerant.",
        &[("font-size", "12"), ("fill", POWER_COLOUR)],
    )?;

    svg.rect(
        MCU_X,
        TOP,
        MCU_RIGHT - MCU_X,
        body_bottom - TOP,
        "#f4f4f4",
        "#000000",
    )?;
    svg.text(
        MCU_X + 10,
        TOP + 24,
        chip_name(gpios),
        &[("font-size", "15"), ("font-weight", "bold")],
    )?;
    svg.text(
        MCU_X + 10,
        TOP + 42,
        "board (3V3 logic)",
        &[("font-size", "12")],
    )?;

    let mut y = TOP;
    for (part, rows) in &groups {
        let box_height = GROUP_HEAD + rows.len() as u32 * ROW_H;
        svg.rect(
            PART_X,
            y,
            PART_RIGHT - PART_X,
            box_height,
            "#f4f4f4",
            "#000000",
        )?;
        svg.text(
            PART_X + 10,
            y + 24,
            part.name(),
            &[("font-size", "15"), ("font-weight", "bold")],
        )?;
        for (i, row) in rows.iter().enumerate() {
            let row_y = y + GROUP_HEAD + i as u32 * ROW_H + ROW_H / 2;
            draw_row(&mut svg, row, row_y)?;
        }
        if *part == Part::G2 {
            draw_power_side(&mut svg, y + GROUP_HEAD)?;
        }
        y += box_height + GROUP_GAP;
    }

    let mut y = body_bottom + 34;
    svg.text(
        MCU_X,
        y,
        "Power and ground",
        &[("font-size", "14"), ("font-weight", "bold")],
    )?;
    for power in &POWER {
        y += 18;
        let text = format!(
            "{} {} to {} {}{}",
            power.from.0.name(),
            power.from.1,
            power.to.0.name(),
            power.to.1,
            if power.note.is_empty() {
                String::new()
            } else {
                format!(": {}", power.note)
            }
        );
        svg.text(MCU_X, y, &text, &[("font-size", "12")])?;
    }
    y += 18;
    svg.text(
        MCU_X,
        y,
        "The protocol runs on the board's USB connector (USB-Serial-JTAG); logs on UART0 TX.",
        &[("font-size", "12")],
    )?;
    y += 30;
    let mut x = MCU_X;
    for (colour, what) in [
        (OUT_COLOUR, "MCU output"),
        (IN_COLOUR, "MCU input"),
        (ANALOG_COLOUR, "analog (ADC1)"),
        (POWER_COLOUR, "power"),
        (GROUND_COLOUR, "ground"),
        (MOTOR_COLOUR, "motor leads"),
    ] {
        svg.line(x, y - 4, x + 30, y - 4, colour)?;
        svg.text(x + 36, y, what, &[("font-size", "12")])?;
        x += 160;
    }
    svg.finish()
}

fn chip_name(gpios: &Gpios) -> &'static str {
    match gpios.chip {
        "esp32c6" => "ESP32-C6",
        _ => "ESP32-C3",
    }
}

/// The rows of one part: its signal wires, then its power wires from the MCU.
fn rows(gpios: &Gpios, part: Part) -> Vec<Row> {
    let signals = WIRES
        .iter()
        .filter(|w| w.part == part)
        .map(|w| signal_row(gpios, w));
    let power = POWER
        .iter()
        .filter(|p| p.from.0 == Part::Mcu && p.to.0 == part)
        .map(power_row);
    signals.chain(power).collect()
}

fn signal_row(gpios: &Gpios, wire: &Wire) -> Row {
    let gpio = format!("GPIO{}", gpios.gpio(wire.signal));
    let (arrow, colour, kind) = match wire.direction {
        Direction::Out => ("→", OUT_COLOUR, "output"),
        Direction::In => ("←", IN_COLOUR, "input"),
        Direction::Analog => ("←", ANALOG_COLOUR, "analog"),
    };
    let fitted = fitted(&wire.fitted, wire.part_pin);
    let under = if fitted.is_empty() {
        wire.note.to_string()
    } else {
        format!("{fitted} · {}", wire.note)
    };
    Row {
        over: format!(
            "{gpio} {arrow} {} {} ({kind})",
            short_name(wire.part),
            wire.part_pin
        ),
        mcu_pin: gpio,
        part_pin: wire.part_pin,
        under,
        colour,
    }
}

fn power_row(power: &PowerWire) -> Row {
    let ground = power.from.1 == "GND";
    Row {
        mcu_pin: power.from.1.to_string(),
        part_pin: power.to.1,
        over: format!(
            "{} — {} {}",
            power.from.1,
            short_name(power.to.0),
            power.to.1
        ),
        under: power.note.to_string(),
        colour: if ground { GROUND_COLOUR } else { POWER_COLOUR },
    }
}

fn short_name(part: Part) -> &'static str {
    match part {
        Part::G2 => "G2",
        other => other.name(),
    }
}

/// What to fit on a wire, in words ("" for a plain wire).
fn fitted(fitted: &Fitted, part_pin: &str) -> String {
    match *fitted {
        Fitted::Wire => String::new(),
        Fitted::PullDown { ohm } => format!("fit {} from the wire to GND", ohms(ohm)),
        Fitted::PullUp {
            ohm,
            required: true,
        } => format!("fit {} from the wire to 3V3", ohms(ohm)),
        Fitted::PullUp {
            ohm,
            required: false,
        } => format!("{} to 3V3 recommended (internal pull-up on)", ohms(ohm)),
        Fitted::LowPass { ohm, nf } => format!(
            "fit {} in series, {} from the pin to GND",
            ohms(ohm),
            nanofarads(nf)
        ),
        Fitted::Divider {
            top_ohm,
            bottom_ohm,
            nf,
        } => format!(
            "fit {} from {part_pin} to the pin, {} and {} from the pin to GND",
            ohms(top_ohm),
            ohms(bottom_ohm),
            nanofarads(nf)
        ),
    }
}

fn ohms(ohm: f32) -> String {
    if ohm >= 1_000.0 {
        format!("{} kΩ", ohm / 1_000.0)
    } else {
        format!("{ohm} Ω")
    }
}

fn nanofarads(nf: f32) -> String {
    format!("{nf} nF")
}

fn draw_row(svg: &mut Svg, row: &Row, y: u32) -> Result<()> {
    svg.line(MCU_RIGHT, y, PART_X, y, row.colour)?;
    svg.dot(MCU_RIGHT, y, row.colour)?;
    svg.dot(PART_X, y, row.colour)?;
    svg.text_anchored(
        MCU_RIGHT - 8,
        y + 5,
        &row.mcu_pin,
        "end",
        &[("font-size", "13"), ("font-weight", "bold")],
    )?;
    svg.text(
        PART_X + 8,
        y + 5,
        row.part_pin,
        &[("font-size", "13"), ("font-weight", "bold")],
    )?;
    let mid = (MCU_RIGHT + PART_X) / 2;
    svg.text_anchored(mid, y - 6, &row.over, "middle", &[("font-size", "12")])?;
    if !row.under.is_empty() {
        svg.text_anchored(
            mid,
            y + 15,
            &row.under,
            "middle",
            &[("font-size", "11"), ("fill", "#444444")],
        )?;
    }
    Ok(())
}

/// The G2's power side: the supply on `VIN`/`GND`, the motor on `OUTA`/`OUTB`, from [`POWER`].
fn draw_power_side(svg: &mut Svg, top: u32) -> Result<()> {
    for (i, part) in [Part::Supply, Part::Motor].into_iter().enumerate() {
        let wires: Vec<&PowerWire> = POWER
            .iter()
            .filter(|p| p.from.0 == part && p.to.0 == Part::G2)
            .collect();
        let box_top = top + i as u32 * (wires.len() as u32 + 1) * ROW_H;
        let box_height = wires.len() as u32 * ROW_H + 24;
        svg.rect(
            SIDE_X,
            box_top,
            SIDE_RIGHT - SIDE_X,
            box_height,
            "#f4f4f4",
            "#000000",
        )?;
        svg.text(
            SIDE_X + 34,
            box_top + 20,
            part.name(),
            &[("font-size", "14"), ("font-weight", "bold")],
        )?;
        for (j, wire) in wires.iter().enumerate() {
            let y = box_top + 24 + j as u32 * ROW_H + ROW_H / 2;
            let colour = match (part, wire.from.1) {
                (Part::Supply, "+") => POWER_COLOUR,
                (Part::Supply, _) => GROUND_COLOUR,
                _ => MOTOR_COLOUR,
            };
            svg.line(PART_RIGHT, y, SIDE_X, y, colour)?;
            svg.dot(PART_RIGHT, y, colour)?;
            svg.dot(SIDE_X, y, colour)?;
            svg.text_anchored(
                PART_RIGHT - 8,
                y + 5,
                wire.to.1,
                "end",
                &[("font-size", "13"), ("font-weight", "bold")],
            )?;
            svg.text(
                SIDE_X + 8,
                y + 5,
                wire.from.1,
                &[("font-size", "13"), ("font-weight", "bold")],
            )?;
        }
    }
    Ok(())
}

/// A small SVG writer over xml-rs's `EventWriter`.
struct Svg {
    writer: EventWriter<Vec<u8>>,
}

impl Svg {
    fn new() -> Result<Self> {
        let writer = EmitterConfig::new()
            .perform_indent(true)
            .write_document_declaration(true)
            .create_writer(Vec::new());
        Ok(Self { writer })
    }

    fn open(&mut self, name: &str, attrs: &[(&str, String)]) -> Result<()> {
        let mut event = XmlEvent::start_element(name);
        if name == "svg" {
            event = event.default_ns("http://www.w3.org/2000/svg");
        }
        for (key, value) in attrs {
            event = event.attr(*key, value);
        }
        self.writer.write(event)?;
        Ok(())
    }

    fn close(&mut self) -> Result<()> {
        self.writer.write(XmlEvent::end_element())?;
        Ok(())
    }

    fn empty(&mut self, name: &str, attrs: &[(&str, String)]) -> Result<()> {
        self.open(name, attrs)?;
        self.close()
    }

    fn comment(&mut self, text: &str) -> Result<()> {
        self.writer.write(XmlEvent::comment(text))?;
        Ok(())
    }

    fn rect(&mut self, x: u32, y: u32, w: u32, h: u32, fill: &str, stroke: &str) -> Result<()> {
        self.empty(
            "rect",
            &[
                ("x", x.to_string()),
                ("y", y.to_string()),
                ("width", w.to_string()),
                ("height", h.to_string()),
                ("fill", fill.into()),
                ("stroke", stroke.into()),
            ],
        )
    }

    fn line(&mut self, x1: u32, y1: u32, x2: u32, y2: u32, colour: &str) -> Result<()> {
        self.empty(
            "line",
            &[
                ("x1", x1.to_string()),
                ("y1", y1.to_string()),
                ("x2", x2.to_string()),
                ("y2", y2.to_string()),
                ("stroke", colour.into()),
                ("stroke-width", "2".into()),
            ],
        )
    }

    fn dot(&mut self, x: u32, y: u32, colour: &str) -> Result<()> {
        self.empty(
            "circle",
            &[
                ("cx", x.to_string()),
                ("cy", y.to_string()),
                ("r", "3".into()),
                ("fill", colour.into()),
            ],
        )
    }

    fn text(&mut self, x: u32, y: u32, text: &str, style: &[(&str, &str)]) -> Result<()> {
        self.text_anchored(x, y, text, "start", style)
    }

    fn text_anchored(
        &mut self,
        x: u32,
        y: u32,
        text: &str,
        anchor: &str,
        style: &[(&str, &str)],
    ) -> Result<()> {
        let mut attrs = vec![
            ("x", x.to_string()),
            ("y", y.to_string()),
            ("text-anchor", anchor.to_string()),
        ];
        attrs.extend(style.iter().map(|(k, v)| (*k, v.to_string())));
        self.open("text", &attrs)?;
        self.writer.write(XmlEvent::characters(text))?;
        self.close()
    }

    fn finish(mut self) -> Result<String> {
        self.close()?;
        let mut bytes = self.writer.into_inner();
        bytes.write_all(b"\n")?;
        String::from_utf8(bytes).context("the SVG writer wrote invalid UTF-8")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn svg() -> String {
        drawing(&wiring::ESP32C3).unwrap()
    }

    #[test]
    fn the_drawing_is_well_formed_svg() {
        let svg = svg();
        roxmltree::Document::parse(&svg).expect("well-formed XML");
        usvg::Tree::from_str(&svg, &usvg::Options::default()).expect("an SVG that usvg reads");
    }

    #[test]
    fn every_wire_is_labelled_with_its_gpio_and_the_parts_pin() {
        let svg = svg();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let texts: Vec<&str> = doc
            .descendants()
            .filter(|n| n.has_tag_name("text"))
            .filter_map(|n| n.text())
            .collect();
        for wire in &WIRES {
            let gpio = format!("GPIO{}", wiring::ESP32C3.gpio(wire.signal));
            assert!(
                texts
                    .iter()
                    .any(|t| t.starts_with(&gpio) && t.contains(wire.part_pin)),
                "no label with {gpio} and {}",
                wire.part_pin
            );
        }
        for power in &POWER {
            assert!(
                texts.iter().any(|t| t.contains(power.to.1)),
                "{:?}",
                power.to
            );
        }
    }

    #[test]
    fn the_check_fails_on_a_stale_drawing_only() {
        let svg = svg();
        let path =
            std::env::temp_dir().join(format!("kerfmeter-wiring-{}.svg", std::process::id()));
        std::fs::write(&path, &svg).unwrap();
        assert!(check(&path, &svg).is_ok());
        std::fs::write(&path, svg.replace('\n', "\r\n")).unwrap();
        assert!(
            check(&path, &svg).is_ok(),
            "CRLF line ends are the same drawing"
        );
        std::fs::write(&path, svg.replace("GPIO3", "GPIO9")).unwrap();
        let error = check(&path, &svg).unwrap_err().to_string();
        assert!(
            error.contains("GPIO9") && error.contains("cargo xtask wiring"),
            "{error}"
        );
        std::fs::write(&path, svg.trim_end()).unwrap();
        let error = check(&path, &svg).unwrap_err().to_string();
        assert!(error.contains("only the line ends differ"), "{error}");
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn the_drawing_follows_the_table() {
        // Another assignment, another drawing: the drawing is the table's, not a fixed text.
        let moved = Gpios {
            pwm: 8,
            ..wiring::ESP32C3
        };
        let svg = drawing(&moved).unwrap();
        assert!(svg.contains("GPIO8 → G2 PWM"));
        assert!(!svg.contains("GPIO3 → G2 PWM"));
        assert_eq!(
            drawing(&wiring::ESP32C3).unwrap(),
            self::svg(),
            "deterministic"
        );
    }
}
