//! GRBL 1.1's status report, the answer to `?`: `<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>`.
//! Its machine states ([`MachineState`]) and the fields this project reads and writes
//! ([`Status`]): read by the driver ([`Status::parse`]), written by the cutter twin
//! ([`Status`]'s `Display`).

use std::fmt;

/// The machine's state, as a status report names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MachineState {
    /// At rest, ready.
    Idle,
    /// Running a program.
    Run,
    /// Feed hold: `Hold:1` while stopping, `Hold:0` once stopped.
    Hold(u8),
    /// Jogging.
    Jog,
    /// In alarm: G-code is locked until `$X` (or homing).
    Alarm,
    /// The safety door is open (its sub-state).
    Door(u8),
    /// Check mode (`$C`).
    Check,
    /// Homing.
    Home,
    /// Asleep.
    Sleep,
    /// A state this program does not know.
    Other(String),
}

impl MachineState {
    /// The state a report names (`Hold:0` with its sub-state).
    pub fn parse(text: &str) -> Self {
        let (name, sub) = match text.split_once(':') {
            Some((name, sub)) => (name, sub.parse().unwrap_or(0)),
            None => (text, 0),
        };
        match name {
            "Idle" => Self::Idle,
            "Run" => Self::Run,
            "Hold" => Self::Hold(sub),
            "Jog" => Self::Jog,
            "Alarm" => Self::Alarm,
            "Door" => Self::Door(sub),
            "Check" => Self::Check,
            "Home" => Self::Home,
            "Sleep" => Self::Sleep,
            _ => Self::Other(text.to_owned()),
        }
    }
}

impl fmt::Display for MachineState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Hold(n) => write!(f, "Hold:{n}"),
            Self::Door(n) => write!(f, "Door:{n}"),
            Self::Other(s) => f.write_str(s),
            other => write!(f, "{other:?}"),
        }
    }
}

/// The free room a status report's `Bf` field gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferFree {
    /// Free planner blocks.
    pub planner_blocks: u32,
    /// Free receive-buffer bytes.
    pub rx_bytes: u32,
}

/// A status report (`<Idle|MPos:0.000,0.000,0.000|FS:0,0>`); the fields a controller leaves out
/// are `None`.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// The machine's state.
    pub state: MachineState,
    /// Machine position, mm (`MPos`; `None` when it reports `WPos` only).
    pub position_mm: Option<[f64; 3]>,
    /// Work position, mm (`WPos`, which a controller reports instead of `MPos` with `$10=0`).
    pub work_position_mm: Option<[f64; 3]>,
    /// Feed now, mm/min, and spindle (laser) value (`FS`).
    pub feed_mm_per_min: Option<f64>,
    /// The spindle (laser) value now (`FS`).
    pub spindle_s: Option<f64>,
    /// Free planner blocks and free receive-buffer bytes (`Bf`).
    pub buffer_free: Option<BufferFree>,
}

impl Status {
    /// Parse `<...>`; `None` when `line` is not a status report.
    pub fn parse(line: &str) -> Option<Self> {
        let body = line.strip_prefix('<')?.strip_suffix('>')?;
        let mut fields = body.split('|');
        let mut status = Status {
            state: MachineState::parse(fields.next()?),
            position_mm: None,
            work_position_mm: None,
            feed_mm_per_min: None,
            spindle_s: None,
            buffer_free: None,
        };
        for field in fields {
            let Some((name, value)) = field.split_once(':') else {
                continue;
            };
            let numbers: Vec<f64> = value.split(',').filter_map(|v| v.parse().ok()).collect();
            match (name, numbers.as_slice()) {
                ("MPos", [x, y, z, ..]) => status.position_mm = Some([*x, *y, *z]),
                ("WPos", [x, y, z, ..]) => status.work_position_mm = Some([*x, *y, *z]),
                ("FS", [feed, s]) => {
                    status.feed_mm_per_min = Some(*feed);
                    status.spindle_s = Some(*s);
                }
                ("F", [feed]) => status.feed_mm_per_min = Some(*feed),
                ("Bf", [blocks, bytes]) => {
                    status.buffer_free = Some(BufferFree {
                        planner_blocks: *blocks as u32,
                        rx_bytes: *bytes as u32,
                    })
                }
                _ => {}
            }
        }
        Some(status)
    }
}

/// The report as GRBL 1.1 writes it: the state, then `MPos` or `WPos` (3 decimals), `Bf`, and
/// `FS` (whole numbers; `F` alone without a spindle value), each only when present.
impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "<{}", self.state)?;
        let position = |f: &mut fmt::Formatter<'_>, name: &str, [x, y, z]: [f64; 3]| {
            write!(f, "|{name}:{x:.3},{y:.3},{z:.3}")
        };
        if let Some(p) = self.position_mm {
            position(f, "MPos", p)?;
        }
        if let Some(p) = self.work_position_mm {
            position(f, "WPos", p)?;
        }
        if let Some(b) = self.buffer_free {
            write!(f, "|Bf:{},{}", b.planner_blocks, b.rx_bytes)?;
        }
        match (self.feed_mm_per_min, self.spindle_s) {
            (Some(feed), Some(s)) => write!(f, "|FS:{feed:.0},{s:.0}")?,
            (Some(feed), None) => write!(f, "|F:{feed:.0}")?,
            _ => {}
        }
        f.write_str(">")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_written_reads_back_as_written() {
        let text = "<Hold:0|MPos:1.000,2.500,-0.125|Bf:15,128|FS:600,250>";
        let status = Status::parse(text).unwrap();
        assert_eq!(status.state, MachineState::Hold(0));
        assert_eq!(status.to_string(), text);
        let work = "<Idle|WPos:1.000,2.000,-3.500|FS:0,0>";
        assert_eq!(Status::parse(work).unwrap().to_string(), work);
        assert_eq!(Status::parse("Idle"), None);
    }
}
