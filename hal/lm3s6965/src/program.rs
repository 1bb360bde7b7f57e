//! Program mode of the QEMU board (the idle loader, when QEMU's working directory holds
//! `program.nc`): the program file read through semihosting is the one loader's line source
//! (`millac::rt::program`, `millac::rt::loader`); its result lines go into the result file and
//! the log. Every accepted block runs; the run reports the final position (or the hold's) and
//! exits QEMU. The first refused line stops the reading; the blocks before it still run.
use core::fmt;

use cortex_m_semihosting::nr;
use millac::protocol::table::record::RecordError;
use millac::rt::loader::Finished;
use millac::rt::program::{Program, ProgramFile, Said};

use crate::voice::{exit, log_error, text, Text};
use crate::{results, semihost};
use millac::rt::status::STATUS;

/// `program.nc` open for reading, and the errors said so far for the log.
pub struct SemihostProgram {
    fd: usize,
    /// The loader's error messages for the log, written once the machine is idle: the logger's
    /// critical section (tens of microseconds for a long line) must not hold back a frame, at a
    /// rapid period of 38 us. (The result file has them at once.)
    errors: heapless::Vec<Text, 2>,
}

/// `program.nc`, if QEMU's working directory holds it (None: serial mode). Idle loader.
pub fn open() -> Option<SemihostProgram> {
    semihost::open(b"program.nc\0", nr::open::R).map(|fd| SemihostProgram {
        fd,
        errors: heapless::Vec::new(),
    })
}

impl ProgramFile for SemihostProgram {
    const NAME: &'static str = "program.nc";

    fn read(&mut self, buf: &mut [u8]) -> Option<usize> {
        semihost::read(self.fd, buf)
    }

    fn result(&mut self, kind: Said, what: fmt::Arguments) {
        let t = text(what);
        results::line(format_args!("{}: {}", kind.word(), t));
        match kind {
            Said::Error => {
                let _ = self.errors.push(t);
            }
            Said::Stop => defmt::info!("{=str}: {=str}", kind.word(), t.as_str()),
            Said::Alarm | Said::Chatter => defmt::warn!("{=str}: {=str}", kind.word(), t.as_str()),
        }
    }
}

/// `program` as the loader's line source; with a refused settings record nothing runs (see "At
/// start-up" in `crate::storage`): said into the result file, and QEMU exits with failure.
/// Idle loader.
pub fn console(
    mut program: SemihostProgram,
    refused: Option<RecordError>,
) -> Program<SemihostProgram> {
    if let Some(e) = refused {
        program.result(
            Said::Error,
            format_args!(
                "settings: {}; nothing runs (fix or remove {})",
                e.message(),
                crate::files::SETTINGS_NAME
            ),
        );
        end(program, false);
    }
    Program::new(program)
}

/// The run has ended (`loader::run` returned `finished`): exits QEMU, with success unless a
/// line or the file was refused or the run held. Idle loader.
pub fn finish(console: Program<SemihostProgram>, finished: Option<Finished>) -> ! {
    if finished == Some(Finished::Held) {
        held_exit();
    }
    let ok = console.ok();
    end(console.into_file(), ok)
}

/// The end of a run: the errors into the log, the file closed, the position reported; exit.
fn end(program: SemihostProgram, ok: bool) -> ! {
    for t in &program.errors {
        log_error(t);
    }
    semihost::close(program.fd);
    report_position(false);
    exit(ok)
}

/// Program mode: the run ends on a hold with the machine standing: `millac: hold blocks=N
/// position=x,y,z` (the exact position), exit with failure.
pub fn held_exit() -> ! {
    report_position(true);
    exit(false);
}

/// The run's last line, `millac: [hold ]blocks=N position=x,y,z` (the exact position as the
/// frame last published it), into the result file and the log.
fn report_position(held: bool) {
    let [x, y, z] = STATUS.position();
    let blocks = STATUS.blocks_done.get();
    results::line(format_args!(
        "millac: {}blocks={} position={},{},{}",
        if held { "hold " } else { "" },
        blocks,
        x,
        y,
        z
    ));
    if held {
        defmt::warn!(
            "held: blocks={=u32} position={=i32},{=i32},{=i32}",
            blocks,
            x,
            y,
            z
        );
    } else {
        defmt::info!(
            "done: blocks={=u32} position={=i32},{=i32},{=i32}",
            blocks,
            x,
            y,
            z
        );
    }
}
