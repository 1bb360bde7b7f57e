//! The QEMU board's voice (init, the loader and the tasks, the panic handler; never the frame or
//! pulse-end ISR): a human log message formatted before defmt's logger takes its critical section,
//! errors into the result file and the log, and the exit through semihosting.
//!
//! # Output
//!
//! Two channels, never mixed:
//! - the log, for people: defmt (`defmt::error!/warn!/info!`, no timestamp) through
//!   `defmt-semihosting`'s global logger on semihosting stdout; the host decodes the frames with
//!   this ELF's `.defmt` table (`millac_qemu::defmtlog`). The logger takes a critical section, so
//!   the frame and pulse-end ISRs never log, and the others format their text first ([`text`]);
//! - the results, for the tools: `result.txt` (`crate::files::RESULT_FILE`, see "Result file"
//!   there; [`crate::results`]): errors, alarms, the hold and the final position.
//!
//! The exit status (semihosting SYS_EXIT) is failure after an error, a hold or a panic.
use core::fmt::{self, Write as _};

use cortex_m_semihosting::debug;

use crate::results;

/// One human log message, formatted before the logger is taken: defmt's logger holds a critical
/// section while it encodes and writes, so the text is ready and that section stays short.
pub type Text = heapless::String<200>;

pub fn text(args: fmt::Arguments) -> Text {
    let mut t = Text::new();
    // A message too long for the buffer keeps what fitted.
    let _ = t.write_fmt(args);
    t
}

/// An error: `error: <what>` in the result file (the run fails) and in the log. Init and tasks,
/// never the frame or pulse-end ISR.
pub fn error(what: fmt::Arguments) {
    log_error(&report(what));
}

/// `error: <what>` in the result file, at once (one semihosting write, no critical section);
/// returns the text for the log.
pub fn report(what: fmt::Arguments) -> Text {
    let t = text(what);
    results::line(format_args!("error: {}", t));
    t
}

/// An error in the log. The logger's critical section lasts about 30 instructions per byte (1 197
/// for a 38-character line, measured at shift 4): 19 us in which no frame can start.
pub fn log_error(t: &Text) {
    defmt::error!("{=str}", t.as_str());
}

/// Reports an error ([`error`]) and leaves QEMU with a failure status. Init and idle.
pub fn fail(what: fmt::Arguments) -> ! {
    error(what);
    exit(false)
}

/// Leaves QEMU through semihosting (success or failure status). Never returns on QEMU; on a
/// debugger that continues, parks the core.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::nop();
    }
}

/// Set by the first panic: a panic inside the panic handler (the logger taken where the first
/// panic struck) only exits.
static PANICKED: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Any context: `panic: <message>` in the result file and in the log, exit with failure.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    if !PANICKED.swap(true, core::sync::atomic::Ordering::Relaxed) {
        let t = text(format_args!("{}", info));
        results::line(format_args!("panic: {}", t));
        defmt::error!("panic: {=str}", t.as_str());
    }
    exit(false)
}
