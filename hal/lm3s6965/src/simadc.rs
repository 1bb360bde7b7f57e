//! The lockstep simulated ADC of the QEMU board: the host (millac-qemu's `cosim` bridge) answers
//! every sample request with three 12-bit codes computed from the encoder counts, through two
//! FIFOs in QEMU's working directory, reached through semihosting. Opened in init; `exchange` is
//! called by the sampler task; [`crate::semihost::LogFile`] (the AC log) by the AC task.
//!
//! The protocol (header, request, response) is `millac::wire`, the one definition the host shares.
//! init opens `adc.req` (mode "r+", i.e. O_RDWR: never creates the file and never blocks; if it
//! does not exist the AC is absent and the firmware runs exactly as without it), then `adc.resp`
//! (mode "r": blocks until the host has opened its write end) and reads the header. Per sample
//! (Timer 2, `sample_hz`) the sampler writes a request and reads the codes. A semihosting call stops
//! the whole emulator until it returns, and under `-icount` virtual time does not advance
//! meanwhile: the exchange is lockstep and deterministic. The host answers `wire::NO_CONVERSION`
//! when the simulated ADC does not convert (a dropout, `--fault dropout@S`): that sample is
//! [`Conversion::Missed`], the sampler's clock goes on and the AC period, seeing no fresh samples,
//! holds (`Alarm::NoSamples`), exactly as on a board whose converter stops. If a read or write
//! fails (the host went away), the sampler stops its timer and the firmware exits with
//! `error: simulated ADC lost` (without samples the AC cannot guard the cut).
use cortex_m_semihosting::nr;

use crate::semihost::{open, read_exact, write_all};
use millac::ports::{Conversion, ForceTorqueAdc};
use millac::wire::{self, Header, Request};

/// The open simulated ADC: request and response handles.
pub struct SimAdc {
    req: usize,
    resp: usize,
    /// The host has gone: the ADC answers no more.
    lost: bool,
    /// The sound codes of the last response, until taken.
    sound: Option<[u16; wire::SOUND_PER_SAMPLE]>,
    /// The tool in the simulated spindle (the last M6's, as the status words tell it).
    tool: u8,
}

impl SimAdc {
    /// Opens the FIFOs and reads the header: `(adc, flags)`, or None when the host serves no ADC
    /// (no `adc.req`) or the handshake fails. Init context (blocks until the host is ready).
    pub fn open() -> Option<(SimAdc, u32)> {
        let req = open(crate::files::REQ_FILE.as_bytes(), nr::open::RW)?;
        let resp = open(crate::files::RESP_FILE.as_bytes(), nr::open::R)?;
        let mut h = [0u8; Header::LEN];
        if !read_exact(resp, &mut h) {
            return None;
        }
        let header = Header::parse(&h)?;
        Some((
            SimAdc {
                req,
                resp,
                lost: false,
                sound: None,
                tool: 0,
            },
            header.flags,
        ))
    }
}

impl ForceTorqueAdc for SimAdc {
    /// One lockstep conversion: sends the sample index and the encoder counts, returns the codes
    /// [T, Fu, Fv]; `Missed` on the host's no-conversion response, `Lost` if the host has gone.
    /// Sampler task.
    fn sample(&mut self, index: u32, encoder: [i32; 3]) -> Conversion {
        // Gone before: no more semihosting calls, every tick is missed.
        if self.lost {
            return Conversion::Missed;
        }
        // The loader writes the tool at an M6 (the machine standing); read while it writes
        // (this task preempted it), the tool is the one before until the next sample.
        if let Some((_, t)) = millac::rt::status::STATUS.fitted_tool() {
            self.tool = t.number;
        }
        let q = Request {
            index,
            encoder,
            spindle_rpm: crate::loader::spindle_rpm(),
            tool: u32::from(self.tool),
        }
        .emit();
        let mut r = [0u8; wire::Response::LEN];
        if !write_all(self.req, &q) || !read_exact(self.resp, &mut r) {
            self.lost = true;
            self.sound = None;
            return Conversion::Lost;
        }
        let response = wire::Response::parse(&r);
        self.sound = (!response.sound.contains(&wire::NO_SOUND)).then_some(response.sound);
        match response.codes {
            Some(codes) => Conversion::Fresh(codes),
            None => Conversion::Missed,
        }
    }

    /// The sound codes of the last response (None: the plant has no microphone). Sampler task.
    fn sound(&mut self) -> Option<[u16; wire::SOUND_PER_SAMPLE]> {
        self.sound.take()
    }
}
