//! The tool table (loader task; host tests and tools): what the program's T words and G43 H name,
//! one entry per tool number 1..=[`MAX_TOOLS`] (T0 is no tool). Lengths in picometres, as the
//! work offsets keep them (see [`super::offsets`]).

/// Tools in the table: T1..=T16 (grblHAL's default table size; T0 is the empty spindle).
pub const MAX_TOOLS: usize = 16;

/// The most flutes a tool may have (a record or a `$T` line with more is refused).
pub const MAX_FLUTES: u8 = 32;

/// The cutter's shape, for the set-up's checks and the adaptive control's limits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum ToolKind {
    /// A flat end mill (the default of an entry nobody described).
    #[default]
    Flat,
    /// A ball end mill.
    Ball,
    /// A drill.
    Drill,
}

impl ToolKind {
    /// The kinds in code order: code n is `KINDS[n]` (the settings record's byte, `$T`'s K word).
    pub const KINDS: [ToolKind; 3] = [ToolKind::Flat, ToolKind::Ball, ToolKind::Drill];

    /// The kind's code: 0 flat, 1 ball, 2 drill.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The kind of a code, None for a code that names none.
    pub fn from_code(code: u8) -> Option<ToolKind> {
        Self::KINDS.get(code as usize).copied()
    }

    /// What the kind is called in listings.
    pub const fn name(self) -> &'static str {
        match self {
            ToolKind::Flat => "flat end mill",
            ToolKind::Ball => "ball end mill",
            ToolKind::Drill => "drill",
        }
    }
}

/// One tool. An entry nobody described is all zero: length 0 (G43 H of it offsets nothing, as
/// grblHAL's table), diameter 0, no flute count, and no limits (fitted by an M6, the AC only
/// measures it: `crate::ac::strength::of_tool`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tool {
    /// Length offset (G43 H), picometres.
    pub length_pm: i64,
    /// Diameter, picometres (G10 L1 R is the radius).
    pub diameter_pm: i64,
    /// Cutting edges (0: not known), at most [`MAX_FLUTES`].
    pub flutes: u8,
    pub kind: ToolKind,
    /// The permissible cutting force and torque of this cutter (N, N m); 0 = from its diameter
    /// and kind (`crate::ac::strength::of_tool`). Finite, not negative, and listable exactly
    /// ([`crate::gcode::number::listable_f32`]).
    pub force_limit_n: f32,
    pub torque_limit_nm: f32,
}

/// The table: tool n is entry n - 1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ToolTable {
    tools: [Tool; MAX_TOOLS],
}

impl ToolTable {
    /// Tool `n` (1..=MAX_TOOLS), or None for T0 and numbers beyond the table.
    pub fn get(&self, n: u32) -> Option<&Tool> {
        self.tools.get((n as usize).checked_sub(1)?)
    }

    /// Sets tool `n`; false (nothing changed) when `n` is not 1..=MAX_TOOLS.
    pub fn set(&mut self, n: u32, tool: Tool) -> bool {
        match (n as usize)
            .checked_sub(1)
            .and_then(|i| self.tools.get_mut(i))
        {
            Some(t) => {
                *t = tool;
                true
            }
            None => false,
        }
    }

    /// The tools with their numbers.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &Tool)> {
        self.tools
            .iter()
            .enumerate()
            .map(|(i, t)| (i as u32 + 1, t))
    }
}
