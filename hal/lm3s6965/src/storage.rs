//! The QEMU board's settings storage: the persistent settings record
//! (`millac::protocol::table::record`) in a host file, [`crate::files::SETTINGS_FILE`] in QEMU's working
//! directory, reached through semihosting. Init loads it; the loader task (serial mode) stores it
//! after every accepted `$N=value` (through `millac::protocol::table::Persistent`).
//!
//! The host (`millac-qemu serve --settings FILE`) makes that name a link to the operator's file,
//! so the firmware reads and writes the real file. A store truncates the file and writes the whole
//! image in one SYS_WRITE: QEMU stopped between the two leaves an empty or short file, which the
//! record's length and CRC checks refuse at the next start (defaults and an alarm), never garbage.
//! No rename-into-place: it would replace the host's link instead of writing through it.
//!
//! # At start-up
//!
//! init loads the persistent record through `crate::storage::FileStorage` (`settings.bin` in
//! QEMU's working directory): a valid record gives the frame and the parser its NC settings and
//! the AC controller its AC settings (`$250=0` turns the AC's feed cap off even when the host
//! enables it); no file gives the defaults, silently. A refused record (truncated, corrupt, of
//! another version, invalid values) gives the defaults and:
//! - serial mode: `ALARM:120` and `[MSG:<why>; defaults loaded]` after the banner, G-code locked
//!   until `$X` (`Protocol::settings_refused`); `$RST=*` or any `$N=value` stores a new record;
//! - program mode (`program.nc`): `error: settings: <why>; nothing runs` (log and result file)
//!   and exit with failure before anything moves: a program run unattended must not run on
//!   settings the operator did not choose, and there is no `$X` to acknowledge them.
use cortex_m_semihosting::nr;

use crate::semihost::{close, read, write_all};
use millac::ports::SettingsStorage;

/// The settings file (a unit struct: the name is [`crate::files::SETTINGS_FILE`]).
pub struct FileStorage;

/// Opens the settings file with a semihosting open mode; None if the host refuses.
fn open(mode: usize) -> Option<usize> {
    crate::semihost::open(crate::files::SETTINGS_FILE.as_bytes(), mode)
}

impl SettingsStorage for FileStorage {
    /// The file's bytes, at most `buf.len()` (a longer file fills `buf`, and the record's length
    /// check refuses it); None when there is no file (or the host cannot open it). A read error
    /// gives the bytes read before it, which the record's checks refuse. Init.
    fn load(&mut self, buf: &mut [u8]) -> Option<usize> {
        let fd = open(nr::open::R_BINARY)?;
        let mut n = 0;
        while let Some(rest) = buf.get_mut(n..) {
            if rest.is_empty() {
                break;
            }
            match read(fd, rest) {
                Some(0) | None => break,
                Some(got) => n += got,
            }
        }
        close(fd);
        Some(n)
    }

    /// Truncates the file and writes `image` in one call; false if the host refused any step.
    /// Loader task.
    fn store(&mut self, image: &[u8]) -> bool {
        let Some(fd) = open(nr::open::W_TRUNC_BINARY) else {
            return false;
        };
        let all = write_all(fd, image);
        close(fd) && all
    }
}
