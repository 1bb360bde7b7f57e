//! The lockstep simulated ADC of the QEMU board: the host (millac-qemu's `cosim` bridge) answers
//! every sample request with three 12-bit codes computed from the encoder counts, through two
//! FIFOs in QEMU's working directory, reached through semihosting. Opened in init; `exchange` is
//! called by the sampler task; [`LogFile`] (the AC log) by the AC task.
//!
//! # Protocol (all integers little endian)
//!
//! 1. init opens `adc.req` (mode "r+", i.e. O_RDWR: never creates the file and never blocks; if it
//!    does not exist the AC is absent and the firmware runs exactly as without it), then `adc.resp`
//!    (mode "r": blocks until the host has opened its write end).
//! 2. The host writes an 8-byte header: `b"MAC1"`, u32 flags (bit 0: AC enabled, i.e. the
//!    controller's feed cap is applied; clear: measure and log only).
//! 3. Per sample (Timer 2, `sample_hz`): the firmware writes 16 bytes to `adc.req` (u32 sample
//!    index from 0, i32 encoder counts X, Y, Z in BLU) and reads 6 bytes from `adc.resp` (u16 codes
//!    T, Fu, Fv). A semihosting call stops the whole emulator until it returns, and under
//!    `-icount` virtual time does not advance meanwhile: the exchange is lockstep and
//!    deterministic.
//! 4. When QEMU exits its ends close and the host reads EOF. If a read or write fails (the host
//!    went away), the sampler stops its timer and the firmware exits with
//!    `error: simulated ADC lost` (without samples the AC cannot guard the cut).
use cortex_m_semihosting::{nr, syscall};

/// Header magic.
pub const MAGIC: [u8; 4] = *b"MAC1";
/// Header flag: the AC's feed cap is applied.
pub const FLAG_AC_ENABLED: u32 = 1;

/// Opens `name` (NUL-terminated) with a semihosting open mode; None if the host refuses.
fn open(name: &[u8], mode: usize) -> Option<usize> {
    // SAFETY: SYS_OPEN with a NUL-terminated name, its length without the NUL and a valid mode.
    let fd = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) } as isize;
    (fd != -1).then_some(fd as usize)
}

/// Writes all of `bytes` to `fd`; false if the host did not take them all.
fn write_all(fd: usize, bytes: &[u8]) -> bool {
    // SAFETY: SYS_WRITE from a buffer we own, its length; returns the bytes NOT written.
    unsafe { syscall!(WRITE, fd, bytes.as_ptr(), bytes.len()) == 0 }
}

/// Fills `buf` from `fd`; false on a short read (EOF or error).
fn read_exact(fd: usize, buf: &mut [u8]) -> bool {
    // SAFETY: SYS_READ into a buffer we own, at most its length; returns the bytes NOT read.
    unsafe { syscall!(READ, fd, buf.as_mut_ptr(), buf.len()) == 0 }
}

/// The open simulated ADC: request and response handles.
pub struct SimAdc {
    req: usize,
    resp: usize,
}

impl SimAdc {
    /// Opens the FIFOs and reads the header: `(adc, flags)`, or None when the host serves no ADC
    /// (no `adc.req`) or the handshake fails. Init context (blocks until the host is ready).
    pub fn open() -> Option<(SimAdc, u32)> {
        let req = open(b"adc.req\0", nr::open::RW)?;
        let resp = open(b"adc.resp\0", nr::open::R)?;
        let mut h = [0u8; 8];
        if !read_exact(resp, &mut h) || h[..4] != MAGIC {
            return None;
        }
        let flags = u32::from_le_bytes([h[4], h[5], h[6], h[7]]);
        Some((SimAdc { req, resp }, flags))
    }

    /// One lockstep conversion: sends the sample index and the encoder counts, returns the codes
    /// [T, Fu, Fv]; None if the host has gone. Sampler task.
    pub fn exchange(&mut self, index: u32, encoder: [i32; 3]) -> Option<[u16; 3]> {
        let mut q = [0u8; 16];
        q[0..4].copy_from_slice(&index.to_le_bytes());
        q[4..8].copy_from_slice(&encoder[0].to_le_bytes());
        q[8..12].copy_from_slice(&encoder[1].to_le_bytes());
        q[12..16].copy_from_slice(&encoder[2].to_le_bytes());
        if !write_all(self.req, &q) {
            return None;
        }
        let mut r = [0u8; 6];
        if !read_exact(self.resp, &mut r) {
            return None;
        }
        Some([
            u16::from_le_bytes([r[0], r[1]]),
            u16::from_le_bytes([r[2], r[3]]),
            u16::from_le_bytes([r[4], r[5]]),
        ])
    }
}

/// A file in QEMU's working directory written through semihosting (the AC log). Opened in init,
/// written by the AC task. Write errors are ignored: the log never stops the machine.
pub struct LogFile(usize);

impl LogFile {
    /// Creates (truncates) `name` (NUL-terminated).
    pub fn create(name: &[u8]) -> Option<LogFile> {
        open(name, nr::open::W_TRUNC).map(LogFile)
    }

    pub fn write(&mut self, bytes: &[u8]) {
        let _ = write_all(self.0, bytes);
    }
}
