//! The program "tape" (the paper's tape reader): bytes in chunks -> numbered lines -> parser ->
//! look-ahead -> validated blocks. One piece of code for the firmware loader (idle task) and the
//! host tool's pre-check, so both accept and reject exactly the same programs.
use super::lines::{LineError, Lines};
use super::{carry_signs, Expansion, GcodeError, Lookahead, Parsed, Parser};
use crate::ac::{apply_ceiling, FeedCeiling};
use crate::nc::{Block, FrameConfig, Sealed};
use crate::settings::Settings;

/// Why the tape stopped: a line refused before parsing, or by the parser.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TapeError {
    Line { line: u32, error: LineError },
    Gcode(GcodeError),
}

impl TapeError {
    /// The line number of the refused line.
    pub const fn line(&self) -> u32 {
        match self {
            TapeError::Line { line, .. } => *line,
            TapeError::Gcode(e) => e.line,
        }
    }
}

impl core::fmt::Display for TapeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TapeError::Line { line, error } => write!(f, "line {}: {}", line, error.message()),
            TapeError::Gcode(e) => write!(f, "{}", e),
        }
    }
}

/// Tape reader state. `feed` and `finish` hand each block to `emit` in program order, complete:
/// the one place where a block is finished (parser: geometry, feed and the sign byte; look-ahead:
/// the deceleration flag; an enabled AC's feed ceiling; [`Block::seal`]: the frame's register
/// image). After an error or M2/M30 the tape ignores the rest.
pub struct Tape {
    lines: Lines,
    reader: Reader,
    done: bool,
    finish: Finish,
}

/// The parser, the look-ahead and a canned cycle still being expanded.
struct Reader {
    parser: Parser,
    lookahead: Lookahead,
    /// A cycle whose blocks are not all emitted yet, and the SIGN lines after the last one that was.
    pending: Option<(Expansion, u8)>,
}

impl Reader {
    /// One line through the parser; its blocks to the look-ahead (at most `room` emitted; a
    /// cycle's remaining blocks stay pending). True at the program's end.
    fn line(
        &mut self,
        n: u32,
        text: &str,
        room: usize,
        emit: &mut impl FnMut(Block),
    ) -> Result<bool, TapeError> {
        let signs = self.parser.signs();
        let parsed = self.parser.line(n, text).map_err(TapeError::Gcode)?;
        if let Parsed::Expand(c) = parsed {
            self.pending = Some((c, signs));
            self.pump(room, emit);
            return Ok(false);
        }
        Ok(take(parsed, &mut self.lookahead, emit))
    }

    /// Emits a pending cycle's next blocks through the look-ahead, at most `room` of them.
    fn pump(&mut self, room: usize, emit: &mut impl FnMut(Block)) {
        let Some((mut c, mut signs)) = self.pending.take() else {
            return;
        };
        let settings = *self.parser.settings();
        let mut emitted = 0;
        while emitted < room {
            let Some(mut b) = c.next_block(&settings) else {
                return;
            };
            signs = carry_signs(&mut b.motion, signs);
            if let Some(prev) = self.lookahead.push(b) {
                emit(prev);
                emitted += 1;
            }
        }
        if !c.done() {
            self.pending = Some((c, signs));
        }
    }
}

/// What the tape does to every block before it emits it.
#[derive(Clone, Copy)]
struct Finish {
    cfg: FrameConfig,
    q0: u32,
    ceiling: Option<FeedCeiling>,
}

impl Finish {
    fn block(&self, b: Block) -> Sealed {
        finish_block(b, self.ceiling, &self.cfg, self.q0)
    }
}

/// The last steps of a block before the queue, after the parser and the look-ahead: an enabled
/// AC's feed ceiling, then the frame's register image ([`Block::seal`]). The tape runs it on every
/// block it emits; the host simulation runs it on a loaded program it queues with the AC enabled.
pub fn finish_block(
    mut b: Block,
    ceiling: Option<FeedCeiling>,
    cfg: &FrameConfig,
    q0: u32,
) -> Sealed {
    if let Some(c) = ceiling {
        apply_ceiling(&mut b, c, q0);
    }
    b.seal(cfg)
}

impl Tape {
    pub fn new(settings: Settings) -> Self {
        Tape {
            lines: Lines::new(),
            reader: Reader {
                parser: Parser::new(settings),
                lookahead: Lookahead::new(),
                pending: None,
            },
            done: false,
            finish: Finish {
                cfg: FrameConfig::from_settings(&settings),
                q0: settings.q0,
                ceiling: None,
            },
        }
    }

    /// A tape for a run with the adaptive control enabled: feed blocks are queued with the AC's
    /// feed ceiling applied (see [`apply_ceiling`]).
    pub fn with_ac_ceiling(settings: Settings, ceiling: FeedCeiling) -> Self {
        let mut t = Tape::new(settings);
        t.finish.ceiling = Some(ceiling);
        t
    }

    /// The parser (modes, programmed position after the last accepted block).
    pub fn parser(&self) -> &Parser {
        &self.reader.parser
    }

    /// Restores the work offsets and the tool table the settings record kept (see
    /// [`Parser::set_work`]).
    pub fn set_work(&mut self, w: &super::Work) {
        self.reader.parser.set_work(w);
    }

    /// Whether a line changed what the settings record keeps (see [`Parser::take_work_changed`]).
    pub fn take_work_changed(&mut self) -> bool {
        self.reader.parser.take_work_changed()
    }

    /// True while a canned cycle's blocks are still to be emitted ([`Tape::pump`]).
    pub fn pending(&self) -> bool {
        self.reader.pending.is_some()
    }

    /// Emits at most `room` more blocks of a pending canned cycle. Loader task: a streamed cycle
    /// fills the queue as it empties, so that a cycle of any number of pecks never waits for
    /// room inside the loader.
    pub fn pump(&mut self, room: usize, mut emit: impl FnMut(Sealed)) {
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        self.reader.pump(room, &mut emit);
    }

    /// True after M2/M30 or an error: nothing more is read.
    pub fn done(&self) -> bool {
        self.done
    }

    /// Takes the next bytes. On an error the blocks accepted before it have all been emitted
    /// (none is held back), then the error is returned.
    pub fn feed(&mut self, bytes: &[u8], mut emit: impl FnMut(Sealed)) -> Result<(), TapeError> {
        if self.done {
            return Ok(());
        }
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        let mut result = Ok(());
        let (reader, done) = (&mut self.reader, &mut self.done);
        self.lines.feed(bytes, |n, text| {
            step(reader, done, &mut result, &mut emit, n, text)
        });
        self.settle(result, emit)
    }

    /// End of the tape: a last line without a newline, then the held block.
    pub fn finish(&mut self, mut emit: impl FnMut(Sealed)) -> Result<(), TapeError> {
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        let mut result = Ok(());
        if !self.done {
            let (reader, done) = (&mut self.reader, &mut self.done);
            self.lines
                .finish(|n, text| step(reader, done, &mut result, &mut emit, n, text));
        }
        self.done = true;
        self.settle(result, emit)
    }

    /// Streaming (a serial sender): one line, already split and numbered by the caller. An error
    /// refuses this line only (the parser is unchanged) and the next line is read as usual; the
    /// blocks before it have been emitted or are held as usual. M2/M30 ends the program: the held
    /// block is emitted and the modes return to power-up (the position stays), so the next program
    /// starts fresh, as grbl does. Loader task.
    pub fn line(
        &mut self,
        n: u32,
        text: &str,
        mut emit: impl FnMut(Sealed),
    ) -> Result<(), TapeError> {
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        if self.reader.line(n, text, usize::MAX, &mut emit)? {
            self.reader.parser.end_program();
        }
        Ok(())
    }

    /// [`Tape::line`] emitting at most `room` blocks: the rest of a canned cycle stays pending
    /// ([`Tape::pump`]). Loader task.
    pub fn line_within(
        &mut self,
        n: u32,
        text: &str,
        room: usize,
        mut emit: impl FnMut(Sealed),
    ) -> Result<(), TapeError> {
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        if self.reader.line(n, text, room, &mut emit)? {
            self.reader.parser.end_program();
        }
        Ok(())
    }

    /// Emits the held block, decelerating at its end as at the end of a program: for a streamed
    /// program whose next line has not arrived while the machine would otherwise stop (a lone
    /// line from a sender runs at once). Loader task.
    pub fn flush(&mut self, mut emit: impl FnMut(Sealed)) {
        let finish = self.finish;
        let mut emit = |b: Block| emit(finish.block(b));
        // A pending cycle's blocks come before the held one (the loader never flushes while a
        // cycle is pending; a host reading does not leave one).
        self.reader.pump(usize::MAX, &mut emit);
        if let Some(b) = self.reader.lookahead.flush() {
            emit(b);
        }
    }

    /// Soft reset of a streamed program: the held block is emitted (the blocks already queued
    /// run as well) and the modes return to power-up; the position stays. Loader task.
    pub fn reset(&mut self, emit: impl FnMut(Sealed)) {
        self.flush(emit);
        self.reader.parser.reset_modes();
    }

    /// Soft reset during motion: the frame stopped at `at` (BLU) with the SIGN lines `signs` and
    /// dropped the queued blocks; the held block is dropped too, the modes return to power-up and
    /// the parser stands where the machine stands. Loader task.
    pub fn abort(&mut self, at: [i32; 3], signs: u8) {
        self.reader.pending = None;
        self.flush(|_| {});
        self.reader.parser.reset_modes();
        self.reader.parser.jogged_to(at, signs);
    }

    /// A jog planned on a copy of the parser ran to `end` with the SIGN lines `signs`: the
    /// parser follows it (see `Parser::jogged_to`). Loader task.
    pub fn jogged_to(&mut self, end: [i32; 3], signs: u8) {
        self.reader.parser.jogged_to(end, signs);
    }

    /// The tool change set the new tool's length offset (see `Parser::set_tool_length`).
    /// Loader task.
    pub fn set_tool_length(&mut self, tlo_pm: i64, how: super::ToolLength) {
        self.reader.parser.set_tool_length(tlo_pm, how);
    }

    /// True when a block is held by the look-ahead (see [`Tape::flush`]).
    pub fn holds_a_block(&self) -> bool {
        self.reader.lookahead.holds()
    }

    fn settle(
        &mut self,
        result: Result<(), TapeError>,
        mut emit: impl FnMut(Block),
    ) -> Result<(), TapeError> {
        if self.done {
            self.reader.pump(usize::MAX, &mut emit);
            if let Some(b) = self.reader.lookahead.flush() {
                emit(b);
            }
        }
        result
    }
}

fn step(
    reader: &mut Reader,
    done: &mut bool,
    result: &mut Result<(), TapeError>,
    emit: &mut impl FnMut(Block),
    n: u32,
    text: Result<&str, LineError>,
) -> bool {
    let parsed = match text {
        Ok(t) => reader.line(n, t, usize::MAX, emit),
        Err(error) => Err(TapeError::Line { line: n, error }),
    };
    match parsed {
        Ok(end) => {
            if end {
                *done = true;
            }
            !end
        }
        Err(e) => {
            *result = Err(e);
            *done = true;
            false
        }
    }
}

/// Hands an accepted line's blocks to the look-ahead (the block it held is emitted when a new
/// one comes); a stop (M0, M6) or the end (M2/M30) emits the held block, which decelerates, as
/// the machine stops there. True at the program's end.
fn take(parsed: Parsed, lookahead: &mut Lookahead, emit: &mut impl FnMut(Block)) -> bool {
    let mut push = |b: Block| {
        if let Some(prev) = lookahead.push(b) {
            emit(prev);
        }
    };
    match parsed {
        Parsed::Nothing => false,
        Parsed::Block(b) => {
            push(b);
            false
        }
        // A probing move runs alone and ends standing: out at once, decelerating.
        Parsed::Probe(b, _) => {
            push(b);
            if let Some(b) = lookahead.flush() {
                emit(b);
            }
            false
        }
        Parsed::Two(a, b) => {
            push(a);
            push(b);
            false
        }
        // An expansion is emitted by the reader (it never comes here).
        Parsed::Expand(_) => false,
        Parsed::Stop(_) | Parsed::End => {
            if let Some(b) = lookahead.flush() {
                emit(b);
            }
            matches!(parsed, Parsed::End)
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::nc::{Motion, Sealed};
    use std::vec::Vec;

    /// A streamed program, line by line: an error refuses only its line (the next lines run from
    /// the unchanged state), the look-ahead holds the last block until the next line or a flush,
    /// and M2 ends the program (held block out, modes back to power-up, position kept).
    #[test]
    fn streamed_lines_refuse_one_line_and_flush_on_demand() {
        let mut tape = Tape::new(Settings::default());
        let mut out: Vec<Sealed> = Vec::new();
        tape.line(1, "G21 G91 G1 F100 X1", |b| out.push(b)).unwrap();
        assert!(out.is_empty() && tape.holds_a_block());
        let e = tape.line(2, "G1 X1 Q7", |b| out.push(b)).unwrap_err();
        assert_eq!(e.line(), 2);
        tape.line(3, "X1", |b| out.push(b)).unwrap();
        assert_eq!(out.len(), 1);
        tape.flush(|b| out.push(b));
        assert_eq!(out.len(), 2);
        assert!(!tape.holds_a_block());
        // Both lines ran 1 mm in G91, and the flushed one decelerates (it ends the motion).
        let Motion::Linear(l) = out[1].motion else {
            panic!("{:?}", out[1])
        };
        assert!(
            l.decel && l.decel_below > 0,
            "sealed for deceleration: {l:?}"
        );
        assert_eq!(tape.parser().position(), [787, 0, 0]);
        tape.line(4, "Y1", |b| out.push(b)).unwrap();
        tape.line(5, "M2", |b| out.push(b)).unwrap();
        assert_eq!(out.len(), 3);
        // After M2: G1 G17 G90 M5 as grbl; the units (mm), the feed and the position stay.
        let m = tape.parser().modes();
        assert_eq!(
            (m.motion, m.distance, m.units),
            (
                crate::gcode::MotionMode::Linear,
                crate::gcode::Distance::Absolute,
                crate::gcode::Units::Mm
            )
        );
        assert_eq!(tape.parser().position(), [787, 394, 0]);
        tape.line(6, "X0", |b| out.push(b)).unwrap();
        tape.flush(|b| out.push(b));
        assert_eq!(out.len(), 4, "X0 runs at the kept feed");
        assert!(!tape.done());
    }

    /// After a jog the parser stands where the jog ended, exactly: an absolute move starts from
    /// there, increments add to it, and the modes are the program's (a jog changes none).
    #[test]
    fn the_parser_follows_a_jog() {
        let mut tape = Tape::new(Settings::default());
        let mut out: Vec<Sealed> = Vec::new();
        tape.line(1, "G21 G91 G1 F100 X1", |b| out.push(b)).unwrap();
        tape.flush(|b| out.push(b));
        let modes = tape.parser().modes();
        // A jog (planned elsewhere) to X = 1000 BLU, Y = -5 BLU.
        tape.jogged_to([1000, -5, 0], 0b001);
        assert_eq!(tape.parser().position(), [1000, -5, 0]);
        assert_eq!(tape.parser().modes(), modes);
        tape.line(2, "X0.0254", |b| out.push(b)).unwrap();
        tape.line(3, "G90 X0 Y0", |b| out.push(b)).unwrap();
        tape.flush(|b| out.push(b));
        let steps: Vec<([u32; 3], u8)> = out[1..]
            .iter()
            .map(|b| match b.motion {
                Motion::Linear(l) => (l.steps, l.signs),
                m => panic!("{m:?}"),
            })
            .collect();
        // +0.0254 mm = +10 BLU from the jog's end, then back to 0: 1010 BLU in X, 5 in Y.
        assert_eq!(steps[0].0, [10, 0, 0]);
        assert_eq!(steps[1].0, [1010, 5, 0]);
        assert_eq!(steps[1].1 & 0b011, 0b010);
    }

    /// A soft reset during motion drops the held block (it never runs), returns the modes to
    /// power-up and leaves the parser where the machine stopped, so the next absolute move is
    /// planned from there.
    #[test]
    fn abort_drops_the_held_block_and_stands_where_the_machine_stopped() {
        let mut tape = Tape::new(Settings::default());
        let mut out: Vec<Sealed> = Vec::new();
        tape.line(1, "G20 G91 G1 F10 X1", |b| out.push(b)).unwrap();
        tape.line(2, "X1", |b| out.push(b)).unwrap();
        assert_eq!(out.len(), 1);
        assert!(tape.holds_a_block());
        tape.abort([4321, 0, 0], 0b001);
        assert!(!tape.holds_a_block());
        assert_eq!(tape.parser().position(), [4321, 0, 0]);
        // Power-up modes: G90 G21 and no feed; a move needs its F again.
        assert!(tape.line(3, "G1 X0", |b| out.push(b)).is_err());
        tape.line(4, "G1 X0 F100", |b| out.push(b)).unwrap();
        tape.flush(|b| out.push(b));
        assert_eq!(out.len(), 2);
        let Motion::Linear(l) = out[1].motion else {
            panic!("{:?}", out[1].motion)
        };
        assert_eq!((l.steps, l.signs & 1), ([4321, 0, 0], 0));
    }
}
