//! The Nucleo-F446RE firmware under QEMU (host): its `qemu` build
//! ([`crate::emulator::firmware::NUCLEO_F446RE_QEMU`]) on the netduinoplus2 machine (STM32F405), with USART2
//! (QEMU's second `-serial`) on a TCP port. [`stream`] sends a G-code program with the grbl
//! protocol, as a simple sender does (soft reset until the banner, one line at a time, each
//! answered `ok`, then `?` until `Idle`), stops QEMU and returns the capture: the PC4..PC9 levels
//! from the GPIOC BSRR stores (see [`crate::emulator::capture::Machine::Netduinoplus2`]) and the
//! instructions per call of the handlers asked for (the frame ISR `TIM2`, the pulse-end ISR
//! `TIM5`).
//!
//! Which blocks meet in the queue depends on the wall clock: the lines come over a TCP port in
//! real time while QEMU runs the frames in virtual time, so a loaded host (slow QEMU) sees every
//! line in time and a quiet one sees the queue run dry between lines (a line then starts from a
//! stop instead of chaining). [`StreamOptions::queue_first`] removes that: the sender holds the
//! machine (`!`) before the first line and resumes it (`~`) before the last, so the whole program
//! is queued before anything moves and runs as from a file (the budget benchmark's mode).
//!
//! Measured on Debian's QEMU 7.2 (netduinoplus2): no RCC, flash interface, GPIO, DMA or IWDG
//! model (unimplemented devices: reads 0, writes ignored and logged by `-d unimp`); TIM2..TIM5 and
//! the USARTs are modelled; USART2 is the second `-serial`; the USART raises RXNE interrupts but
//! no TXE interrupt; DWT CYCCNT is not modelled (reads 0, logged as a read of an unassigned PPB
//! address). The firmware's `qemu` feature works around exactly these.
use crate::emulator::capture::{run_capture, Capture, CaptureSpec, HandlerSpec};
use anyhow::{bail, Context, Result};
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What a streamed session produced.
pub struct Session {
    pub capture: Capture,
    /// The banner lines (up to `[MSG:millac ...]`).
    pub banner: Vec<String>,
    /// Per program line sent: the line and the answers up to its `ok`.
    pub answers: Vec<(String, Vec<String>)>,
    /// The last status report (`<Idle|MPos:...>`).
    pub status: String,
    /// With [`StreamOptions::queue_first`]: the status report just before the release (`~`),
    /// `<Hold:0|MPos:...>` with the start position when nothing moved while the lines came.
    pub held_status: Option<String>,
}

/// A free TCP port on the loopback interface (the OS may hand it to another later).
fn free_port() -> Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// One line from the serial port (without its line end); an error after `deadline`.
fn line(r: &mut BufReader<TcpStream>, deadline: Instant) -> Result<String> {
    let mut l = String::new();
    loop {
        match r.read_line(&mut l) {
            Ok(0) => bail!("serial port closed"),
            Ok(_) if l.ends_with('\n') => return Ok(l.trim_end().to_string()),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => return Err(e.into()),
        }
        if Instant::now() > deadline {
            bail!("no answer in time (so far `{l}`)");
        }
    }
}

/// What the sender saw.
struct Talk {
    banner: Vec<String>,
    answers: Vec<(String, Vec<String>)>,
    status: String,
    held_status: Option<String>,
}

/// The next status report (`<...>`), skipping other lines.
fn status_report(r: &mut BufReader<TcpStream>, deadline: Instant) -> Result<String> {
    loop {
        let a = line(r, deadline).context("status report")?;
        if a.starts_with('<') {
            return Ok(a);
        }
    }
}

/// The grbl side of a session: banner, lines, status until idle (`queue_first`: see
/// [`StreamOptions::queue_first`]).
fn talk(addr: &str, program: &str, queue_first: bool, deadline: Instant) -> Result<Talk> {
    let stream = loop {
        match TcpStream::connect(addr) {
            Ok(s) => break s,
            Err(e) if Instant::now() < deadline => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => bail!("connect {addr}: {e}"),
        }
    };
    stream.set_read_timeout(Some(Duration::from_millis(500)))?;
    let mut w = stream.try_clone()?;
    let mut r = BufReader::new(stream);
    // The first banner went out before we connected: soft reset until one comes.
    let mut banner = Vec::new();
    'reset: loop {
        w.write_all(&[0x18])?;
        let wait = Instant::now() + Duration::from_secs(1);
        while let Ok(l) = line(&mut r, wait.min(deadline)) {
            let done = l.starts_with("[MSG:millac");
            banner.push(l);
            if done {
                break 'reset;
            }
        }
        if Instant::now() > deadline {
            bail!("no banner: {banner:?}");
        }
    }
    let mut answers = Vec::new();
    let lines: Vec<&str> = program
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    if queue_first {
        w.write_all(b"!")?;
    }
    let mut held_status = None;
    for (k, l) in lines.iter().enumerate() {
        let held = queue_first && k + 1 < lines.len();
        if queue_first && !held {
            w.write_all(b"?")?;
            held_status = Some(status_report(&mut r, deadline)?);
            w.write_all(b"~")?;
        }
        w.write_all(format!("{l}\n").as_bytes())?;
        let mut got = Vec::new();
        loop {
            let a = line(&mut r, deadline).with_context(|| {
                if held {
                    format!(
                        "line `{l}`, held (`!`) until the last line: a program of more blocks than \
                         the queue holds never gets this `ok`"
                    )
                } else {
                    format!("line `{l}`")
                }
            })?;
            let end = a == "ok" || a.starts_with("error:") || a.starts_with("ALARM:");
            got.push(a);
            if end {
                break;
            }
        }
        answers.push((l.to_string(), got));
    }
    // `?` until the machine is idle.
    let status = loop {
        w.write_all(b"?")?;
        let s = status_report(&mut r, deadline)?;
        if s.starts_with("<Idle") {
            break s;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Ok(Talk {
        banner,
        answers,
        status,
        held_status,
    })
}

/// How [`stream_with`] runs a session.
#[derive(Clone, Debug)]
pub struct StreamOptions {
    /// `-icount shift`: one instruction = 2^shift ns.
    pub shift: u32,
    /// Functions of the ELF to time (e.g. `TIM2`).
    pub handlers: Vec<String>,
    /// Wall-clock limit of the session.
    pub timeout: Duration,
    /// Trace the long calls of a handler ([`crate::emulator::capture::CaptureSpec::trace`]).
    pub trace: Option<(usize, u64)>,
    /// Hold the machine (`!`) before the first line and resume it (`~`) before the last: every
    /// line but the last is queued before anything moves, so the blocks meet in the queue as in
    /// a program read from a file, whatever the wall clock (the first block is queued with the
    /// deceleration of a block without a successor: the loader lets the held block run when the
    /// machine is idle; the last line, M2, runs once the machine stands, as always). The program
    /// must fit the block queue (the sender waits for an `ok` that never comes otherwise).
    pub queue_first: bool,
}

impl StreamOptions {
    /// Shift 4, the handlers `names`, `timeout`, no trace, lines sent as they are answered.
    pub fn new(names: &[&str], timeout: Duration) -> StreamOptions {
        StreamOptions {
            shift: 4,
            handlers: names.iter().map(|n| n.to_string()).collect(),
            timeout,
            trace: None,
            queue_first: false,
        }
    }
}

/// Runs the `qemu` build `elf` on netduinoplus2 in `dir` (created; the capture's files go there)
/// with `-icount shift`, streams `program` over USART2 and returns the session once the machine
/// reports `Idle` after the last line. `handlers`: functions of `elf` to time (e.g. `TIM2`).
pub fn stream(
    elf: &Path,
    dir: &Path,
    program: &str,
    shift: u32,
    handlers: &[&str],
    timeout: Duration,
) -> Result<Session> {
    let opts = StreamOptions {
        shift,
        ..StreamOptions::new(handlers, timeout)
    };
    stream_with(elf, dir, program, &opts)
}

/// [`stream`] with all its options.
pub fn stream_with(elf: &Path, dir: &Path, program: &str, opts: &StreamOptions) -> Result<Session> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let addr = format!("127.0.0.1:{}", free_port()?);
    let mut spec = CaptureSpec::netduinoplus2(elf, dir);
    spec.icount_shift = opts.shift;
    spec.extra_args = vec![
        "-serial".into(),
        "null".into(),
        "-serial".into(),
        format!("tcp:{addr},server=on,wait=off"),
        "-monitor".into(),
        "none".into(),
    ];
    spec.handlers = opts
        .handlers
        .iter()
        .map(|h| HandlerSpec::from_elf(elf, h))
        .collect::<Result<_>>()?;
    spec.trace = opts.trace;
    let stop = Arc::new(AtomicBool::new(false));
    spec.stop = Some(stop.clone());
    spec.timeout = Duration::MAX;
    let qemu = std::thread::spawn(move || run_capture(&spec));
    let talked = talk(
        &addr,
        program,
        opts.queue_first,
        Instant::now() + opts.timeout,
    );
    stop.store(true, Ordering::SeqCst);
    let capture = qemu
        .join()
        .map_err(|_| anyhow::anyhow!("the QEMU thread panicked"))??;
    let t = talked.with_context(|| {
        format!(
            "streaming to the F446 firmware under QEMU; QEMU stderr:\n{}",
            capture.stderr
        )
    })?;
    Ok(Session {
        capture,
        banner: t.banner,
        answers: t.answers,
        status: t.status,
        held_status: t.held_status,
    })
}

/// MPos of a status report (`<Idle|MPos:1.000,2.000,0.000|...>`), in the report's unit.
pub fn mpos(status: &str) -> Option<[f64; 3]> {
    let m = status.split('|').find_map(|f| f.strip_prefix("MPos:"))?;
    let v: Vec<f64> = m
        .trim_end_matches('>')
        .split(',')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    v.try_into().ok()
}
