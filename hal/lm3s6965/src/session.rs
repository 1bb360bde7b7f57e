//! The session log of the serial mode: `serve.nc` in QEMU's working directory (semihosting),
//! one `millac::wire::SessionLine` per accepted G-code line, jog, early run of the look-ahead's
//! held block, soft reset, move the loader planned itself and stop, in the order the loader fed its tape, so the host can replay the
//! session into exactly the blocks the firmware queued (`millac serve` writes summary.json from
//! it). Written by the loader task in serial mode ([`crate::serial`]). A semihosting write stops
//! the emulator while it runs, so under `-icount` it costs no virtual time. Semihosting, like
//! `program.nc` and `ac.log`: the QEMU board's; if the host refuses the file nothing is written.

use crate::files::SERVE_LOG_FILE;
use millac::protocol::jog::JogRequest;
use millac::wire::SessionLine;

use crate::semihost::LogFile;

/// The open log (None: the host refused the file; then nothing is logged).
pub struct SessionLog(Option<LogFile>);

/// One line of the log: a received line (at most 256 bytes) with the marker around it.
type Line = heapless::String<300>;

impl SessionLog {
    /// Creates (truncates) `serve.nc`. Loader task, once at the start of serial mode.
    pub fn create() -> Self {
        SessionLog(LogFile::create(SERVE_LOG_FILE.as_bytes()))
    }

    /// No log (program mode: the program file is the record).
    pub const fn none() -> Self {
        SessionLog(None)
    }

    fn write(&mut self, l: SessionLine) {
        let Some(f) = self.0.as_mut() else {
            return;
        };
        let mut s = Line::new();
        if l.emit(&mut s).is_ok() {
            f.write(s.as_bytes());
        }
    }
    /// A G-code line `Tape::line` accepted (a line that reads as a marker is only a comment with
    /// no effect, and is left out).
    pub fn gcode(&mut self, line: &str) {
        if !SessionLine::is_marker(line) {
            self.write(SessionLine::Gcode(line));
        }
    }

    /// A jog that was queued.
    pub fn jog(&mut self, jog: &JogRequest) {
        let mut g = Line::new();
        if jog.write_gcode(&mut g).is_ok() {
            // `G1 ...` as the words after `$J=`.
            self.write(SessionLine::Jog(g.strip_prefix("G1 ").unwrap_or(&g)));
        }
    }

    /// The held block ran before the next line came (`Tape::flush`).
    pub fn flush(&mut self) {
        self.write(SessionLine::Flush);
    }

    /// Soft reset (`Tape::reset`).
    pub fn reset(&mut self) {
        self.write(SessionLine::Reset);
    }

    /// A move the loader planned itself (homing, the tool change).
    pub fn planned(&mut self, line: &str) {
        self.write(SessionLine::Move(line));
    }

    /// Where the parser stands after a reset, a homed axis or (`cut`) a stop mid-move.
    pub fn stop(&mut self, at: [i32; 3], signs: u8, cut: bool) {
        self.write(SessionLine::Stop { at, signs, cut });
    }
}
