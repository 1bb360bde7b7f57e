//! The QEMU board's result file: what the host tools read ([`crate::files::RESULT_FILE`] in QEMU's working
//! directory, reached through semihosting; the line formats are in `millac::wire`, "Result file").
//! The human log is defmt on semihosting stdout (the app's global logger): results never go into
//! that stream, so the host can decode the one and parse the other.
//!
//! Each line is formatted into a buffer and written in one SYS_WRITE, which the emulator carries
//! out whole, so lines from different priorities never interleave; no lock, no critical section.
//! Init, the loader, the sampler and AC tasks, the panic handler; never the frame or pulse-end ISR.
use core::fmt::{self, Write as _};
use core::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use cortex_m_semihosting::nr;

use crate::semihost::{open, write_all};

/// The handle of the open file; [`NOT_OPEN`] before [`create`], [`REFUSED`] if the host refused it.
static FD: AtomicUsize = AtomicUsize::new(NOT_OPEN);
const NOT_OPEN: usize = usize::MAX;
const REFUSED: usize = usize::MAX - 1;

/// One result line (an error message, a position).
type Line = heapless::String<256>;

/// Creates (truncates) the result file. Init, first thing (a line written before it creates the
/// file then). False if the host refused it: the results are then lost, the run goes on.
pub fn create() -> bool {
    let fd = open(crate::files::RESULT_FILE.as_bytes(), nr::open::W_TRUNC).unwrap_or(REFUSED);
    FD.store(fd, Relaxed);
    fd != REFUSED
}

/// Writes `args` and a newline as one line (cut at 255 bytes). Write errors are ignored.
pub fn line(args: fmt::Arguments) {
    if FD.load(Relaxed) == NOT_OPEN {
        create();
    }
    let fd = FD.load(Relaxed);
    if fd == REFUSED {
        return;
    }
    let mut l = Line::new();
    // A line too long for the buffer keeps what fitted (`heapless` refuses a whole piece).
    let _ = l.write_fmt(args);
    let _ = l.push('\n');
    if !l.ends_with('\n') {
        l.pop();
        let _ = l.push('\n');
    }
    let _ = write_all(fd, l.as_bytes());
}
