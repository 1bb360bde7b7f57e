//! Co-simulation of the adaptive control (host): the lockstep simulated ADC the QEMU firmware
//! samples (see `hal/lm3s6965/src/simadc.rs` for the firmware side), a [`Plant`] that turns encoder
//! positions into ADC codes, and the parser of the firmware's `ac.log`.
//!
//! # Protocol
//!
//! `millac::wire` (the one definition the firmware shares): two FIFOs in the run directory (QEMU's
//! working directory), created here before QEMU starts: `adc.req` (firmware -> host) and
//! `adc.resp` (host -> firmware). The firmware opens `adc.req` O_RDWR (no create, no block; absent
//! = no AC), then `adc.resp` for reading (blocks until we open its write end). We write the header,
//! then serve requests until EOF (a request in, three codes out). Every request blocks the whole
//! emulator until answered and under `-icount` virtual time stands still meanwhile, so runs are
//! deterministic. The exchange ends when QEMU exits (EOF on `adc.req`); the firmware ends a run
//! itself, also after a long hold (see `millac::rt::ac`). A plant that has no conversion for a
//! sample (`None`: an ADC dropout, see [`crate::host::fault`]) is answered with the wire's reserved
//! `NO_CONVERSION` response: the firmware's sampler goes on, its AC period sees no fresh samples
//! and holds (`Alarm::NoSamples`), and the run ends as a hold with its report. Should the host
//! close the FIFOs instead, the firmware prints `error: simulated ADC lost` and exits with failure.
//!
//! Opening never deadlocks if QEMU dies early: `adc.req` is opened O_NONBLOCK for reading (always
//! succeeds), `adc.resp` O_NONBLOCK for writing in a retry loop that gives up when the runner says
//! QEMU has exited (or after a timeout); only once the firmware holds both ends is `adc.req`
//! reopened blocking for the request reads. `libc` (already in the lock file through other
//! crates) provides `mkfifo` and `O_NONBLOCK`.
use anyhow::{bail, ensure, Context, Result};
use std::ffi::CString;
use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read, Write};
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use millac::wire::{self, AcLogLine, Header, LogState, Request};

/// Request FIFO (firmware -> host).
pub const REQ: &str = crate::lm3s_files::REQ_NAME;
/// Response FIFO (host -> firmware).
pub const RESP: &str = crate::lm3s_files::RESP_NAME;
/// The AC log the firmware writes in the run directory.
pub const AC_LOG: &str = crate::lm3s_files::AC_LOG_NAME;

/// The simulated machine and cutting process behind the ADC: one conversion per request.
pub trait Plant {
    /// Codes [T, Fu, Fv] for sample `index` at virtual time `t_s` = index / sample_hz, given the
    /// encoder positions (BLU) the firmware counted; None: no conversion for this sample (the
    /// ADC does not answer, a dropout).
    fn sample(&mut self, index: u32, t_s: f64, pos_blu: [i64; 3]) -> Option<[u16; 3]>;

    /// The firmware's spindle now turns at `rpm` (the S of a spindle change in a serial
    /// session; called before the first sample at the new speed). A plant without a spindle
    /// ignores it.
    fn spindle_rpm(&mut self, _rpm: u32) -> Result<()> {
        Ok(())
    }

    /// The firmware's M6 has fitted `tool` (called before the first sample with it). A plant
    /// with one tool ignores it.
    fn tool(&mut self, _tool: u8) -> Result<()> {
        Ok(())
    }

    /// The sound channel's codes since the previous sample (after `sample`), oldest first; all
    /// [`wire::NO_SOUND`] for a plant without a microphone (the default).
    fn sound(&mut self) -> [u16; wire::SOUND_PER_SAMPLE] {
        [wire::NO_SOUND; wire::SOUND_PER_SAMPLE]
    }
}

/// One request and its answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exchange {
    pub index: u32,
    pub pos_blu: [i64; 3],
    /// None: answered "no conversion".
    pub codes: Option<[u16; 3]>,
}

/// The bridge thread serving one run.
pub struct Bridge {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Result<Vec<Exchange>>>,
}

/// Creates the FIFO `path` (removing whatever was there).
fn mkfifo(path: &Path) -> Result<()> {
    if std::fs::symlink_metadata(path).is_ok() {
        std::fs::remove_file(path).with_context(|| format!("removing {}", path.display()))?;
    }
    let c = CString::new(path.as_os_str().as_bytes())?;
    // SAFETY: a valid NUL-terminated path; mkfifo only reads it.
    let r = unsafe { libc::mkfifo(c.as_ptr(), 0o600) };
    if r != 0 {
        bail!(
            "mkfifo {}: {}",
            path.display(),
            std::io::Error::last_os_error()
        );
    }
    Ok(())
}

impl Bridge {
    /// Creates the FIFOs in `run_dir` and starts serving `plant` (before QEMU starts).
    /// `sample_hz` gives the virtual time of a sample; `ac_enabled` goes into the header.
    pub fn start(
        run_dir: &Path,
        mut plant: Box<dyn Plant + Send>,
        sample_hz: u32,
        ac_enabled: bool,
    ) -> Result<Bridge> {
        ensure!(sample_hz > 0, "sample rate must be > 0");
        let (req, resp) = (run_dir.join(REQ), run_dir.join(RESP));
        mkfifo(&req)?;
        mkfifo(&resp)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let flags = if ac_enabled { wire::FLAG_AC_ENABLED } else { 0 };
        let thread =
            std::thread::spawn(move || serve(&req, &resp, &flag, flags, sample_hz, plant.as_mut()));
        Ok(Bridge { stop, thread })
    }

    /// Tells the thread QEMU has exited (so it stops waiting for the firmware to open the FIFOs)
    /// and returns every exchange served.
    pub fn finish(self) -> Result<Vec<Exchange>> {
        self.stop.store(true, Ordering::SeqCst);
        self.thread
            .join()
            .map_err(|_| anyhow::anyhow!("cosim bridge thread panicked"))?
    }
}

/// How long the bridge waits for the firmware to open `adc.resp` when nobody says QEMU exited.
const OPEN_TIMEOUT: Duration = Duration::from_secs(600);

fn serve(
    req: &PathBuf,
    resp: &PathBuf,
    stop: &AtomicBool,
    flags: u32,
    sample_hz: u32,
    plant: &mut dyn Plant,
) -> Result<Vec<Exchange>> {
    // Non-blocking reader: exists at once, so the firmware's open of adc.req never waits on us.
    let probe = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(req)
        .with_context(|| format!("opening {}", req.display()))?;
    let start = Instant::now();
    let mut out = loop {
        match OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(resp)
        {
            Ok(f) => break f,
            // ENXIO: no reader yet (the firmware has not reached its open).
            Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {
                if stop.load(Ordering::SeqCst) || start.elapsed() > OPEN_TIMEOUT {
                    // QEMU ended (or never ran the AC): nothing was exchanged.
                    return Ok(Vec::new());
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(e) => return Err(e).with_context(|| format!("opening {}", resp.display())),
        }
    };
    // The firmware holds adc.req open (it opened it before adc.resp): a blocking open returns
    // at once, and reads now block until a request or EOF.
    let mut input = File::open(req).with_context(|| format!("reopening {}", req.display()))?;
    drop(probe);
    let header = Header { flags }.emit();
    let mut log = Vec::new();
    if write_all(&mut out, &header).is_err() {
        return Ok(log);
    }
    let mut q = [0u8; Request::LEN];
    // The spindle speed and the tool of the last request (0: none commanded, none fitted).
    let (mut rpm, mut tool) = (0, 0);
    loop {
        match input.read_exact(&mut q) {
            Ok(()) => {}
            Err(e) if e.kind() == ErrorKind::UnexpectedEof => break,
            Err(e) => return Err(e).context("reading adc.req"),
        }
        let Request {
            index,
            encoder,
            spindle_rpm,
            tool: fitted,
        } = Request::parse(&q);
        if fitted != tool {
            plant.tool(u8::try_from(fitted).context("adc.req: a tool number above 255")?)?;
            tool = fitted;
        }
        if spindle_rpm != 0 && spindle_rpm != rpm {
            plant.spindle_rpm(spindle_rpm)?;
            rpm = spindle_rpm;
        }
        let pos_blu = encoder.map(i64::from);
        let codes = plant.sample(index, f64::from(index) / f64::from(sample_hz), pos_blu);
        let r = wire::Response {
            codes,
            sound: plant.sound(),
        }
        .emit();
        log.push(Exchange {
            index,
            pos_blu,
            codes,
        });
        if write_all(&mut out, &r).is_err() {
            // QEMU went away (EPIPE).
            break;
        }
    }
    Ok(log)
}

/// Writes all bytes to the non-blocking response FIFO (a few bytes: never more than the pipe
/// holds, but retried on EAGAIN all the same).
fn write_all(f: &mut File, mut b: &[u8]) -> std::io::Result<()> {
    while !b.is_empty() {
        match f.write(b) {
            Ok(0) => return Err(ErrorKind::WriteZero.into()),
            Ok(n) => b = &b[n..],
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_micros(50))
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// One line of `ac.log` (one AC period).
#[derive(Clone, Debug, PartialEq)]
pub struct AcRecord {
    /// The period's deadline: sample count * 1000 / sample_hz.
    pub t_ms: u64,
    /// Encoder counts X, Y, Z in BLU at the end of the period's work.
    pub pos_blu: [i64; 3],
    /// Feed number cap the controller computed (0 = hold).
    pub feed_cap: u32,
    pub e: f32,
    pub f_n: f32,
    pub t_nm: f32,
    /// `None` in run, `Some(alarm message)` in hold.
    pub hold: Option<String>,
    /// Running overrun count.
    pub overruns: u32,
    /// The tool in the spindle (0: none fitted).
    pub tool: u8,
}

/// Parses `ac.log` (header row + one line per period; the format is `millac::wire::AcLogLine`).
pub fn parse_ac_log(text: &str) -> Result<Vec<AcRecord>> {
    let mut lines = text.lines();
    let header = lines.next().context("ac.log is empty")?;
    ensure!(
        header == wire::AC_LOG_HEADER.trim_end(),
        "unexpected ac.log header `{header}`"
    );
    lines
        .enumerate()
        .map(|(n, l)| {
            let r = AcLogLine::parse(l)
                .with_context(|| format!("ac.log line {}: `{l}` is not a log line", n + 2))?;
            Ok(AcRecord {
                t_ms: r.t_ms,
                pos_blu: r.pos_blu.map(i64::from),
                feed_cap: r.feed_cap,
                e: r.e,
                f_n: r.f_n,
                t_nm: r.t_nm,
                hold: match r.state {
                    LogState::Run => None,
                    LogState::Hold(m) => Some(m.to_string()),
                },
                overruns: r.overruns,
                tool: r.tool,
            })
        })
        .collect()
}

/// Replays a co-simulation on the host: the firmware's samples, grouped per AC period, and the
/// achieved feed from the logged encoder positions (anti-windup), through a host `AcController`.
/// Returns the controller's output per period, to compare with the firmware's log.
pub fn replay(
    records: &[AcRecord],
    exchanges: &[Exchange],
    nc: &millac::Settings,
    acs: millac::ac::AcSettings,
) -> Result<Vec<millac::ac::AcOutput>> {
    let per = acs.samples_per_period() as usize;
    let mut ctl = millac::ac::AcController::new(
        acs.validated()
            .map_err(|e| anyhow::anyhow!("{}", e.message()))?,
    );
    let mut last = [0i64; 3];
    let mut out = Vec::with_capacity(records.len());
    for (k, rec) in records.iter().enumerate() {
        for x in exchanges.iter().skip(k * per).take(per) {
            if let Some(c) = x.codes {
                ctl.sample(c);
            }
        }
        let d = [0, 1, 2].map(|i| rec.pos_blu[i] - last[i]);
        last = rec.pos_blu;
        ctl.set_achieved(millac::ac::achieved_feed(d, nc, acs.period_ms));
        out.push(ctl.period());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_log() {
        let t = "t_ms,x_blu,y_blu,z_blu,feed_cap,e,f_n,t_nm,state,overruns,tool\n\
                 10,1,-2,0,750,0.95,180.5,0,run,0,0\n\
                 20,3,-2,0,0,-0.2,4320,1.5,hold:sensor stuck at an ADC rail,1,3\n";
        let r = parse_ac_log(t).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].pos_blu, [1, -2, 0]);
        assert_eq!((r[0].tool, r[1].tool), (0, 3));
        assert_eq!(r[0].hold, None);
        assert_eq!(r[1].feed_cap, 0);
        assert_eq!(r[1].hold.as_deref(), Some("sensor stuck at an ADC rail"));
        assert!(parse_ac_log("bad\n").is_err());
        assert!(parse_ac_log(&format!("{}\n1,2,3\n", t.lines().next().unwrap())).is_err());
    }
}
