//! The `$` settings table with its storage: [`Persistent`] answers `$$`, `$N` and the report
//! options from its [`MachineSettings`] and stores every accepted `$N=value` and `$RST=` at once
//! (as grbl writes its EEPROM), before the `ok`. Built in init from [`record::load`]; called by the
//! loader task (serial mode) through the protocol's [`SettingsTable`] hook; host tests.
//!
//! What a stored change does while the firmware runs: `$10` and `$13` (reports) act at once; the
//! NC settings (the frame's configuration, the parser's soft limits) and the AC settings are fixed
//! at init, so a change is listed by `$$` at once but takes effect at the next start.

use core::fmt::{self, Write};

use super::{record, Invalid, MachineSettings, SetError};
use crate::gcode::number::Decimal;
use crate::ports::SettingsStorage;
use crate::protocol::report::ReportOptions;
use crate::protocol::{GrblError, SettingsTable};
use crate::settings::{BoardLimits, Valid};

/// The settings as `$$` lists them (the stored record, or the defaults that replaced a missing or
/// refused one) and the storage that keeps them.
pub struct Persistent<S> {
    /// Validated for [`Persistent::board`] once, where they were made (the record's decode, the
    /// defaults at load, every set): read them through `Deref` (`table.settings.nc.frame_hz`), or
    /// as valid parts (`table.settings.nc()`, `.ac()`).
    pub settings: Valid<MachineSettings>,
    pub storage: S,
    /// The board's limits every set is validated for.
    pub board: BoardLimits,
    /// Counts the changes of `settings.work` made here (`$RST=#`, `$RST=*`, [`Persistent::set_work`]):
    /// the loader gives the parser the table's work offsets when it moves.
    pub work_epoch: u32,
}

impl<S: SettingsStorage> Persistent<S> {
    /// Loads the record from `storage` ([`record::load`]) for `board` (the QEMU board and the
    /// host tools: `BoardLimits::GENERIC`): the table, and how the load went (a
    /// [`record::LoadStatus::Refused`] is the caller's alarm); every later set is validated for
    /// the same limits. The error: the board cannot run the defaults that replace a missing or
    /// refused record.
    pub fn load(mut storage: S, board: BoardLimits) -> Result<(Self, record::LoadStatus), Invalid> {
        let loaded = record::load(&mut storage, &board)?;
        Ok((
            Persistent {
                settings: loaded.settings,
                storage,
                board,
                work_epoch: 0,
            },
            loaded.status,
        ))
    }
}

impl<S: SettingsStorage> Persistent<S> {
    /// The parser's work offsets and tool table, stored (a G10, G28.1 or G30.1 changed them):
    /// validated, stored, and only then taken; [`SetError::Storage`] when the storage refused.
    pub fn set_work(&mut self, work: crate::gcode::Work) -> Result<(), SetError> {
        let new = MachineSettings {
            work,
            ..*self.settings
        }
        .validated(&self.board)
        .map_err(SetError::Invalid)?;
        record::store(&mut self.storage, &new)?;
        self.settings = new;
        self.work_epoch = self.work_epoch.wrapping_add(1);
        Ok(())
    }
}

impl<S: SettingsStorage> SettingsTable for Persistent<S> {
    fn list(&self, out: &mut dyn Write) -> fmt::Result {
        SettingsTable::list(&*self.settings, out)
    }

    /// Validated, stored, and only then taken: a refused value (its grbl error) or a refused store
    /// (`error:7`) changes neither the table nor the record.
    fn set(&mut self, n: u16, value: Decimal) -> Result<(), u8> {
        record::set_persistent(&mut self.settings, &mut self.storage, n, value, &self.board)
            .map_err(|e| e.code())
    }

    fn get(&self, n: u16, out: &mut dyn Write) -> Result<(), u8> {
        SettingsTable::get(&*self.settings, n, out)
    }

    /// `$T`: listed, or set, validated and stored as a G10 L1 is ([`Persistent::set_work`]; the
    /// loader gives the parser the new table).
    fn tool(&mut self, cmd: &str, out: &mut dyn Write) -> Result<(), u8> {
        let tools = &self.settings.work.tools;
        if let Some((n, t)) = super::tools::command(tools, cmd, out).map_err(|e| e.code())? {
            let mut work = self.settings.work;
            work.tools.set(n, t);
            self.set_work(work).map_err(|e| e.code())?;
        }
        Ok(())
    }

    /// `$RST=$`: the default settings, the work offsets and tool table kept; `$RST=#`: the work
    /// offsets, G28/G30 and the tool table cleared, the settings kept; `$RST=*`: both. Stored (this
    /// also replaces a refused record, so the start-up alarm does not come back). Anything else:
    /// `error:3`.
    fn restore(&mut self, what: u8) -> Result<(), u8> {
        let defaults = MachineSettings::default();
        let new = match what {
            b'$' => MachineSettings {
                work: self.settings.work,
                ..defaults
            },
            b'#' => MachineSettings {
                work: crate::gcode::Work::default(),
                ..*self.settings
            },
            b'*' => defaults,
            _ => return Err(GrblError::INVALID_STATEMENT.0),
        };
        let new = new
            .validated(&self.board)
            .map_err(|e| SetError::Invalid(e).code())?;
        record::store(&mut self.storage, &new).map_err(|e| e.code())?;
        if new.work != self.settings.work {
            self.work_epoch = self.work_epoch.wrapping_add(1);
        }
        self.settings = new;
        Ok(())
    }

    fn report_options(&self) -> ReportOptions {
        SettingsTable::report_options(&*self.settings)
    }
}
