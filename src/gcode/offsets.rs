//! Work coordinates (loader task; host tests): the six coordinate systems G54..G59, the G92
//! offset, the G28/G30 positions and the active tool length offset, kept in picometres of machine
//! coordinates, and the conversion between the parser's exact fine units and them.
//!
//! A program coordinate p of axis k is the machine coordinate p + origin, where the origin is the
//! active system's offset, plus the G92 offset when it is applied, plus (Z only) the tool length
//! offset (RS274/NGC's order; LinuxCNC's and grbl's). Offsets are picometres (1e-9 mm): exact
//! for a word of up to 9 decimals in mm or 8 in inches and for any machine position in BLU, so a
//! program moves by exactly what its words say, rounded once to a BLU at the target.

use super::tools::{ToolKind, ToolTable, MAX_FLUTES};

/// What the settings record keeps of the parser (grbl keeps the first three in EEPROM): the six
/// coordinate systems, the G28 and G30 positions, and the tool table. G92 is not kept (grbl's
/// G92 does not survive a reset either).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    pub systems: [[i64; 3]; 6],
    pub g28: [i64; 3],
    pub g30: [i64; 3],
    pub tools: ToolTable,
}

impl Work {
    /// Every offset and length within +-[`MAX_PM`], diameters not negative, at most
    /// [`MAX_FLUTES`] flutes, the limits not negative and listable exactly: what the parser and
    /// `$T` can make, and what a record may hold.
    pub fn valid(&self) -> bool {
        let ok = |v: i64| v.unsigned_abs() <= MAX_PM as u64;
        let lengths = self
            .systems
            .iter()
            .chain([&self.g28, &self.g30])
            .flatten()
            .all(|&v| ok(v));
        let limit = |v: f32| v >= 0.0 && super::number::listable_f32(v);
        lengths
            && self.tools.iter().all(|(_, t)| {
                ok(t.length_pm)
                    && ok(t.diameter_pm)
                    && t.diameter_pm >= 0
                    && t.flutes <= MAX_FLUTES
                    && limit(t.force_limit_n)
                    && limit(t.torque_limit_nm)
                    && matches!(t.kind, ToolKind::Flat | ToolKind::Ball | ToolKind::Drill)
            })
    }
}

/// The largest offset magnitude, picometres (10^9 mm, 1000 km): three of them add up within i64.
pub const MAX_PM: i64 = 1_000_000_000_000_000_000;

/// The persistent offsets (grbl's: the six systems and the two stored positions) and the G92
/// offset (volatile, as grbl's: a soft reset clears it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Offsets {
    /// G54..G59: each system's origin in machine coordinates.
    pub systems: [[i64; 3]; 6],
    /// G28.1 / G30.1: the stored positions, machine coordinates.
    pub g28: [i64; 3],
    pub g30: [i64; 3],
    /// G92: the offset as last set, and whether it is applied (G92.2 suspends it, G92.3 applies
    /// it again, G92.1 clears it).
    pub g92: [i64; 3],
    pub g92_on: bool,
}

impl Offsets {
    /// The G92 offset in effect.
    pub fn g92_applied(&self) -> [i64; 3] {
        if self.g92_on {
            self.g92
        } else {
            [0; 3]
        }
    }

    /// The origin of the program coordinates in machine coordinates for system `system` (0 =
    /// G54) and the tool length offset `tlo` (Z): what `$#`'s WCO is.
    pub fn origin(&self, system: u8, tlo: i64) -> [i64; 3] {
        let s = self.systems.get(system as usize).copied().unwrap_or([0; 3]);
        let g = self.g92_applied();
        [s[0] + g[0], s[1] + g[1], s[2] + g[2] + tlo]
    }
}
