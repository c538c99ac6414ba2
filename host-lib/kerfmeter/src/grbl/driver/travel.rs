//! The machine's travel at connect and before each program: `$130`–`$132` with homing and soft
//! limits from `$$`, the work offsets (`$#`), the parser state (`$G`) and the head's position
//! (`?`), and the refusal of a program that would leave the travel or cannot be bounded
//! ([`super::super::travel`]), before any of it is sent.

use super::super::error::CutterError;
use super::super::extent::Start;
use super::super::offsets::{MM_PER_INCH, Modal, Offsets};
use super::super::protocol::ProgramLine;
use super::super::travel::Travel;
use super::Cutter;
use kerfmeter_grbl::commands;
use kerfmeter_grbl::settings::REPORT_INCHES;

impl Cutter {
    /// The machine's travel as the next program will start in it, as read at connect or before
    /// the last program: after a check pass, which ends with a soft reset, G92 and the tool
    /// length offset are gone and the parser is at G0 G54 G17 G21 G90. `None`: the controller
    /// reports no `$130`–`$132`, and nothing is checked against them.
    pub fn travel(&self) -> Option<Travel> {
        let travel = self.travel.as_ref()?;
        Some(match self.options.check_first {
            true => travel.after_reset(),
            false => travel.clone(),
        })
    }

    /// Read the travel, when the controller reports one: its offsets, parser state and the
    /// head's position with it.
    pub(super) fn read_travel(&mut self) -> Result<(), CutterError> {
        if Travel::reported(&self.settings).is_none() {
            return Ok(());
        }
        let start = self.read_start()?;
        self.travel = Travel::read(&self.settings, start);
        Ok(())
    }

    /// Where a program would start now: `$#`, `$G` and the head's machine position.
    fn read_start(&mut self) -> Result<Start, CutterError> {
        let unreadable = |what: &str, said: &[String]| {
            CutterError::Protocol(format!(
                "the controller reports its travel ($130–$132) but not {what}: it said {said:?}"
            ))
        };
        let said = self.command(commands::PARAMETERS)?;
        let inches = self.settings.get(&REPORT_INCHES) == Some(&1.0);
        let mm_per_unit = if inches { MM_PER_INCH } else { 1.0 };
        let offsets = Offsets::parse(&said, mm_per_unit)
            .ok_or_else(|| unreadable("its work offsets (`$#`)", &said))?;
        let said = self.command(commands::PARSER_STATE)?;
        let modal = said
            .iter()
            .find_map(|l| Modal::parse(l))
            .ok_or_else(|| unreadable("its parser state (`$G`)", &said))?;
        let status = self.status()?;
        let work_offset = offsets.work_offset_mm(modal.coord_system);
        let from_work =
            |w: [f64; 3]| -> [f64; 3] { std::array::from_fn(|i| w[i] + work_offset[i]) };
        let head_mm = status
            .position_mm
            .or(status.work_position_mm.map(from_work))
            .ok_or_else(|| unreadable("where the head is (MPos or WPos)", &[]))?;
        Ok(Start {
            head_mm,
            offsets,
            modal,
        })
    }

    /// Refuse `lines` before any is sent when their moves would leave the machine's travel, or
    /// cannot be bounded. The offsets, the parser state and the head are read again first, and
    /// the program is followed from where it will start ([`Cutter::travel`]).
    pub(super) fn check_travel(&mut self, lines: &[ProgramLine]) -> Result<(), CutterError> {
        self.read_travel()?;
        let Some(travel) = self.travel() else {
            return Ok(());
        };
        let extent = travel.extent(lines).map_err(|u| CutterError::Unbounded {
            line: u.line,
            written: u.written,
            reason: u.reason,
        })?;
        travel
            .check(&extent)
            .map_err(|beyond| CutterError::BeyondTravel { beyond })
    }
}
