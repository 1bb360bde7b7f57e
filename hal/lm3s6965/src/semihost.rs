//! Host files through ARM semihosting, the QEMU board's file I/O: one safe wrapper per call
//! (SYS_OPEN, SYS_READ, SYS_WRITE, SYS_CLOSE). Init and task contexts (the simulated ADC's FIFOs,
//! the AC and session logs, the settings record, the program file); never the frame or pulse-end
//! ISR. A semihosting call stops the emulator until it returns, so under `-icount` it costs no
//! virtual time.
use cortex_m_semihosting::syscall;

/// Opens `name` (NUL-terminated) with a semihosting open mode (`nr::open::*`); None if the host
/// refuses.
pub fn open(name: &[u8], mode: usize) -> Option<usize> {
    // SAFETY: SYS_OPEN with a NUL-terminated name, its length without the NUL and a valid mode.
    let fd = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len().saturating_sub(1)) } as isize;
    (fd != -1).then_some(fd as usize)
}

/// Closes a handle from [`open`]; false if the host refused.
pub fn close(fd: usize) -> bool {
    // SAFETY: SYS_CLOSE of a handle opened by `open`.
    unsafe { syscall!(CLOSE, fd) == 0 }
}

/// Reads at most `buf.len()` bytes: the number read (0 at the end of the file), None on an error.
pub fn read(fd: usize, buf: &mut [u8]) -> Option<usize> {
    // SAFETY: SYS_READ into a buffer we own, at most its length; returns the bytes NOT read (more
    // than asked: an error).
    let left = unsafe { syscall!(READ, fd, buf.as_mut_ptr(), buf.len()) };
    buf.len().checked_sub(left)
}

/// Fills `buf` from `fd`; false on a short read (EOF or error).
pub fn read_exact(fd: usize, buf: &mut [u8]) -> bool {
    read(fd, buf) == Some(buf.len())
}

/// Writes all of `bytes` to `fd`; false if the host did not take them all.
pub fn write_all(fd: usize, bytes: &[u8]) -> bool {
    // SAFETY: SYS_WRITE from a buffer we own, its length; returns the bytes NOT written.
    unsafe { syscall!(WRITE, fd, bytes.as_ptr(), bytes.len()) == 0 }
}

/// A file in QEMU's working directory written through semihosting (the AC log). Opened in init,
/// written by the AC task. Write errors are ignored: the log never stops the machine.
pub struct LogFile(usize);

impl LogFile {
    /// Creates (truncates) `name` (NUL-terminated).
    pub fn create(name: &[u8]) -> Option<LogFile> {
        open(name, cortex_m_semihosting::nr::open::W_TRUNC).map(LogFile)
    }

    pub fn write(&mut self, bytes: &[u8]) {
        let _ = write_all(self.0, bytes);
    }
}

impl millac::rt::actask::LogSink for LogFile {
    fn write(&mut self, bytes: &[u8]) {
        LogFile::write(self, bytes);
    }
}
