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
            },
            loaded.status,
        ))
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

    /// `$RST=$` and `$RST=*`: the defaults, stored (this also replaces a refused record, so the
    /// start-up alarm does not come back). `$RST=#` (millac has no coordinate offsets) and
    /// anything else: `error:3`.
    fn restore(&mut self, what: u8) -> Result<(), u8> {
        match what {
            b'$' | b'*' => {
                let defaults = MachineSettings::default()
                    .validated(&self.board)
                    .map_err(|e| SetError::Invalid(e).code())?;
                record::store(&mut self.storage, &defaults).map_err(|e| e.code())?;
                self.settings = defaults;
                Ok(())
            }
            _ => Err(GrblError::INVALID_STATEMENT.0),
        }
    }

    fn report_options(&self) -> ReportOptions {
        SettingsTable::report_options(&*self.settings)
    }
}
