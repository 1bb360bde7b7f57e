//! G-code lines -> validated blocks (loader task). STUB: the API is fixed, the body is being written.
use crate::nc::Block;
use crate::settings::Settings;

/// What one accepted line produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parsed {
    /// A line with no motion (comment, modal words only, empty).
    Nothing,
    /// One validated block for the queue.
    Block(Block),
    /// M2 / M30: end of program.
    End,
}

/// A rejected line: its number and the reason. Display: "line N: reason".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GcodeError {
    pub line: u32,
}

impl core::fmt::Display for GcodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "line {}: error", self.line)
    }
}

/// Modal G-code state and the programmed position.
pub struct Parser {
    settings: Settings,
    position: [i32; 3],
}

impl Parser {
    pub fn new(settings: Settings) -> Self {
        Parser { settings, position: [0; 3] }
    }
    /// Parses one line. On `Err` no state changed.
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Parsed, GcodeError> {
        let _ = (line_no, text, &self.settings);
        Ok(Parsed::Nothing)
    }
    /// Programmed position after the last accepted block, machine BLU.
    pub fn position(&self) -> [i32; 3] {
        self.position
    }
}

/// One-block look-ahead that decides the `decel` flag of feed blocks.
pub struct Lookahead {
    pending: Option<Block>,
}

impl Default for Lookahead {
    fn default() -> Self {
        Self::new()
    }
}

impl Lookahead {
    pub const fn new() -> Self {
        Lookahead { pending: None }
    }
    /// Takes the newest block; returns the previous one with its `decel` flag decided.
    pub fn push(&mut self, b: Block) -> Option<Block> {
        self.pending.replace(b)
    }
    /// End of program: the held block (a feed block always decelerates at the end).
    pub fn flush(&mut self) -> Option<Block> {
        self.pending.take()
    }
}
