//! The serial port of `serve` (host, `serve`'s threads): one TCP client at a time in front of the
//! firmware's UART, as a serial port has one cable.
//!
//! QEMU's UART0 is a Unix socket of this front ([`Port::qemu_arg`]); the front listens on the
//! session's TCP address and:
//! - takes one client at a time. A client that connects while another is connected gets one line,
//!   `[MSG:millac serve: ...in use...]` ([`REFUSED`]), and is closed; nothing it sends reaches the
//!   firmware (its bytes are read and dropped until it closes, so the line is not lost in a
//!   connection reset). A client that has just closed is waited for (half a second) before a
//!   newcomer is refused, so a sender that reconnects at once is not turned away;
//! - greets a client with the grbl banner (`millac::protocol::report::write_banner`, the text the
//!   firmware sends after a reset), at the start of a line of the firmware's output: senders that
//!   do not reset on open (bCNC, CNCjs) see a grbl, and the machine is not reset by a connection;
//! - forwards the client's bytes once the firmware has said its banner (its UART set up; a
//!   sender that writes at once on connect, while QEMU still boots, loses nothing) and line by
//!   line ([`LineGate`]): realtime bytes
//!   (`millac::protocol::rx::byte::is_realtime`) at once, the bytes of a line when its line end
//!   (CR or LF) comes. A line the client has not finished when it disconnects is dropped with it
//!   and never reaches the firmware, as if the port had been reopened: the next client's first
//!   line starts clean (a client that ended its last line with a lone CR gets the LF the firmware
//!   skips after a CR, so the next client's first line end is its own). A soft reset (0x18) drops the line in progress, as the firmware's own
//!   reset does. Only the bytes of an unfinished line wait (a sender writes its lines whole, and
//!   a character-counting sender's count stays an upper bound of what the firmware holds); a UTF-8
//!   lead byte (0xC2, 0xC3) right before a realtime byte goes with it, so `C2 91` from bCNC and
//!   CNCjs arrives as they sent it. A line longer than the firmware's [`LINE_MAX`] is kept to
//!   `LINE_MAX + 1` bytes, which the firmware refuses at its end (`error:11`) as it would the
//!   whole line;
//! - reads the firmware's output all the time (dropped while nobody is connected), notes the
//!   alarms it reports (`ALARM:N`, `[MSG:AC hold: ...]`; an unlock clears them) and, when the
//!   session ends ([`Port::finish`]), closes the client and asks for one status report (`?`), so
//!   the summary can say in which state the machine ended.
use anyhow::{Context, Result};
use millac::protocol::rx::byte;
use millac::protocol::LINE_MAX;
use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The line a second client gets before it is closed.
pub const REFUSED: &str =
    "[MSG:millac serve: the serial port is in use by another client; one client at a time]";

/// How long a newcomer waits for a connected client that is closing before it is refused.
const GRACE: Duration = Duration::from_millis(500);
/// How long a refused client's bytes are read and dropped before it is closed.
const DRAIN: Duration = Duration::from_secs(2);
/// A client that takes no output for this long is disconnected (the machine goes on).
const WRITE_TIMEOUT: Duration = Duration::from_secs(30);
/// How long [`Port::finish`] waits for the status report it asked for (wall time).
const REPORT_TIMEOUT: Duration = Duration::from_secs(10);
/// Longest output line kept for the alarm and report notes; longer lines are cut.
const NOTE_MAX: usize = 512;

/// What a client's bytes become on their way to the firmware: realtime bytes at once, a line's
/// bytes when it ends, an unfinished line never (dropped with the gate). See the module doc.
#[derive(Debug, Default)]
pub struct LineGate {
    /// The line in progress (at most `LINE_MAX + 1` bytes).
    line: Vec<u8>,
    /// The last line end passed was a CR: the firmware skips an LF that comes next (CRLF ends
    /// one line), so a client that leaves after a lone CR would have the next client's first LF
    /// taken as the pair's second half.
    after_cr: bool,
}

impl LineGate {
    /// Takes `bytes` from the client and appends what goes to the firmware now to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut Vec<u8>) {
        for &b in bytes {
            if b == byte::RESET {
                // The firmware's reset discards the line in progress: so does the gate.
                self.line.clear();
                self.after_cr = false;
                out.push(b);
            } else if byte::is_realtime(b) {
                // A UTF-8 lead byte right before an extended realtime byte goes with it.
                if b >= 0x80 && matches!(self.line.last(), Some(0xC2 | 0xC3)) {
                    out.extend(self.line.pop());
                }
                out.push(b);
            } else if b == b'\n' || b == b'\r' {
                out.append(&mut self.line);
                out.push(b);
                self.after_cr = b == b'\r';
            } else if self.line.len() <= LINE_MAX {
                self.line.push(b);
            }
        }
    }

    /// The client has gone: its unfinished line is dropped, and a lone CR it ended its last line
    /// with gets the LF the firmware then skips (appended to `out`), so the next client's first
    /// line end counts as its own.
    pub fn close(&mut self, out: &mut Vec<u8>) {
        self.line.clear();
        if core::mem::take(&mut self.after_cr) {
            out.push(b'\n');
        }
    }

    /// The bytes of the unfinished line (they never reach the firmware unless it ends).
    pub fn pending(&self) -> &[u8] {
        &self.line
    }
}

/// The connected client.
struct Client {
    id: u64,
    stream: TcpStream,
    /// Greeted and taking output (a client that connected mid-line is greeted at the next line
    /// start).
    joined: bool,
}

/// What the port keeps between its threads.
#[derive(Default)]
struct State {
    client: Option<Client>,
    next_id: u64,
    /// The firmware's output is in the middle of a line.
    mid_line: bool,
    /// The output line so far (for the notes).
    line: Vec<u8>,
    /// The last alarm the firmware reported (cleared by an unlock).
    alarm: Option<String>,
    /// Status reports seen, and the last one.
    reports: u64,
    report: Option<String>,
    /// QEMU's end of the UART closed (or never connected).
    uart_closed: bool,
    /// The firmware has said its banner: its UART is set up and takes bytes. Until then a
    /// client's bytes wait (a byte QEMU's UART took before the firmware enabled its FIFO was
    /// lost with the FIFO's reset: the first byte of a sender's first line, when QEMU booted
    /// slowly).
    ready: bool,
    clients: u64,
    refused: u64,
}

struct Shared {
    state: Mutex<State>,
    /// Signalled when a status report comes or the UART closes.
    changed: Condvar,
    /// QEMU's end, for the clients' bytes and the final `?`.
    uart_tx: Mutex<Option<UnixStream>>,
    /// The port is closing: accept no one, forward nothing more.
    closing: AtomicBool,
}

/// How the session ended, as the port saw it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Ending {
    /// The machine state of the status report asked for at the end (`Idle`, `Run`, `Hold`,
    /// `Alarm`, ...; None: no report came).
    pub state: Option<String>,
    /// The last alarm the firmware reported and no unlock cleared (`ALARM:3`, or the `AC hold:`
    /// message of an AC hold).
    pub alarm: Option<String>,
    /// Clients served, and clients refused because another one was connected.
    pub clients: u64,
    pub refused: u64,
}

/// The port: its threads and QEMU's socket.
pub struct Port {
    shared: Arc<Shared>,
    dir: PathBuf,
    socket: PathBuf,
    threads: Vec<JoinHandle<()>>,
}

impl Port {
    /// Listens on `tcp` for clients and on a fresh Unix socket for QEMU's UART (in a private
    /// temporary directory). Fails with the address when it cannot listen.
    pub fn open(tcp: &str) -> Result<Port> {
        let listener = TcpListener::bind(tcp)
            .with_context(|| format!("listening on the serial port's address {tcp}"))?;
        listener
            .set_nonblocking(true)
            .context("serial port listener")?;
        let dir = private_dir()?;
        let socket = dir.join("uart.sock");
        let uart = UnixListener::bind(&socket)
            .with_context(|| format!("listening on {}", socket.display()))?;
        uart.set_nonblocking(true).context("UART socket")?;
        let shared = Arc::new(Shared {
            state: Mutex::new(State::default()),
            changed: Condvar::new(),
            uart_tx: Mutex::new(None),
            closing: AtomicBool::new(false),
        });
        let threads = vec![
            {
                let (s, d) = (shared.clone(), dir.clone());
                std::thread::spawn(move || uart_loop(&s, uart, d))
            },
            {
                let s = shared.clone();
                std::thread::spawn(move || accept_loop(&s, listener))
            },
        ];
        Ok(Port {
            shared,
            dir,
            socket,
            threads,
        })
    }

    /// QEMU's `-serial` argument: a client of the port's Unix socket.
    pub fn qemu_arg(&self) -> String {
        format!("unix:{}", self.socket.display())
    }

    /// Whether QEMU's end has closed (QEMU ended) or never connected.
    pub fn uart_closed(&self) -> bool {
        lock(&self.shared.state).uart_closed
    }

    /// Ends the session: closes the client, accepts no one, asks the firmware for a status
    /// report (`?`) and waits for it (at most 10 s). QEMU still runs.
    pub fn finish(&self) -> Ending {
        let s = &self.shared;
        s.closing.store(true, Ordering::SeqCst);
        let before = {
            let mut st = lock(&s.state);
            if let Some(c) = st.client.take() {
                let _ = c.stream.shutdown(Shutdown::Both);
            }
            st.reports
        };
        let asked = lock(&s.uart_tx)
            .as_mut()
            .is_some_and(|u| u.write_all(&[byte::STATUS]).is_ok());
        let t0 = Instant::now();
        let mut st = lock(&s.state);
        while asked && st.reports == before && !st.uart_closed {
            let left = REPORT_TIMEOUT.saturating_sub(t0.elapsed());
            if left.is_zero() {
                break;
            }
            st = s
                .changed
                .wait_timeout(st, left)
                .map(|r| r.0)
                .unwrap_or_else(|e| e.into_inner().0);
        }
        let state = (st.reports != before)
            .then(|| st.report.as_deref().and_then(report_state))
            .flatten();
        Ending {
            state,
            alarm: st.alarm.clone(),
            clients: st.clients,
            refused: st.refused,
        }
    }
}

impl Drop for Port {
    /// Stops the threads (after QEMU has gone, its end closes; a QEMU still running is cut off)
    /// and removes the socket's directory.
    fn drop(&mut self) {
        self.shared.closing.store(true, Ordering::SeqCst);
        if let Some(c) = lock(&self.shared.state).client.take() {
            let _ = c.stream.shutdown(Shutdown::Both);
        }
        if let Some(u) = lock(&self.shared.uart_tx).take() {
            let _ = u.shutdown(Shutdown::Both);
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A fresh directory only this user can enter, for QEMU's socket (a Unix socket path must be
/// short, so not under the session's folder).
fn private_dir() -> Result<PathBuf> {
    use std::os::unix::fs::DirBuilderExt;
    static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let tmp = std::env::temp_dir();
    loop {
        let d = tmp.join(format!(
            "millac-port-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::SeqCst)
        ));
        match std::fs::DirBuilder::new().mode(0o700).create(&d) {
            Ok(()) => return Ok(d),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e).with_context(|| format!("creating {}", d.display())),
        }
    }
}

/// The state word of a status report (`<Hold:0|MPos:...>` -> `Hold`).
fn report_state(report: &str) -> Option<String> {
    let body = report.strip_prefix('<')?;
    let word = body.split(['|', '>']).next()?;
    Some(word.split(':').next()?.to_string())
}

/// QEMU's end: accepts its connection, then reads the firmware's output until it closes.
fn uart_loop(s: &Shared, listener: UnixListener, dir: PathBuf) {
    let stream = loop {
        match listener.accept() {
            Ok((u, _)) => break Some(u),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if s.closing.load(Ordering::SeqCst) {
                    break None;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            Err(_) => break None,
        }
    };
    // Connected (or given up): the socket's name is no longer needed.
    drop(listener);
    let _ = std::fs::remove_dir_all(&dir);
    let Some(mut rx) = stream.filter(|u| u.set_nonblocking(false).is_ok()) else {
        lock(&s.state).uart_closed = true;
        s.changed.notify_all();
        return;
    };
    *lock(&s.uart_tx) = rx.try_clone().ok();
    s.changed.notify_all();
    let mut buf = [0u8; 4096];
    loop {
        let n = match rx.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        let mut st = lock(&s.state);
        output(&mut st, &buf[..n]);
        s.changed.notify_all();
    }
    lock(&s.state).uart_closed = true;
    s.changed.notify_all();
}

/// The firmware's output `bytes`: to the client (greeted at a line start), and into the notes.
fn output(st: &mut State, bytes: &[u8]) {
    let mut to_client = Vec::with_capacity(bytes.len() + 64);
    for &b in bytes {
        if let Some(c) = st.client.as_mut().filter(|c| !c.joined && !st.mid_line) {
            c.joined = true;
            greet(&mut to_client);
        }
        if st.client.as_ref().is_some_and(|c| c.joined) {
            to_client.push(b);
        }
        if b == b'\n' {
            let line = String::from_utf8_lossy(&st.line).trim().to_string();
            st.line.clear();
            note(st, &line);
        } else if st.line.len() < NOTE_MAX {
            st.line.push(b);
        }
        st.mid_line = b != b'\n';
        // A client that connected mid-line is greeted at that line's end, not at the next
        // line's first byte: an idle firmware may send none for a long time (a test that
        // connected while the firmware wrote its banner waited for ever for a greeting).
        if let Some(c) = st.client.as_mut().filter(|c| !c.joined && !st.mid_line) {
            c.joined = true;
            greet(&mut to_client);
        }
    }
    if !to_client.is_empty() {
        send(st, &to_client);
    }
}

/// One whole line of the firmware's output.
fn note(st: &mut State, line: &str) {
    if line.starts_with('<') {
        st.reports += 1;
        st.report = Some(line.to_string());
    } else if line.starts_with("ALARM:") {
        st.alarm = Some(line.to_string());
    } else if let Some(m) = line
        .strip_prefix("[MSG:AC hold: ")
        .and_then(|m| m.strip_suffix(']'))
    {
        st.alarm = Some(format!("AC hold: {m}"));
    } else if line == "[MSG:Caution: Unlocked]" {
        st.alarm = None;
    } else if line.starts_with("Grbl ") {
        st.ready = true;
    }
}

/// The banner a client gets when it joins.
fn greet(out: &mut Vec<u8>) {
    let mut s = String::new();
    let _ = millac::protocol::report::write_banner(&mut s);
    out.extend_from_slice(s.as_bytes());
}

/// Writes to the client; a client that cannot take it is disconnected.
fn send(st: &mut State, bytes: &[u8]) {
    if let Some(c) = st.client.as_mut() {
        if c.stream.write_all(bytes).is_err() {
            let _ = c.stream.shutdown(Shutdown::Both);
            st.client = None;
        }
    }
}

/// The TCP side: one client at a time, others refused.
fn accept_loop(s: &Arc<Shared>, listener: TcpListener) {
    let mut readers = Vec::new();
    while !s.closing.load(Ordering::SeqCst) {
        let stream = match listener.accept() {
            Ok((t, _)) => t,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
            Err(_) => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        if stream.set_nonblocking(false).is_err() {
            continue;
        }
        let _ = stream.set_nodelay(true);
        let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
        // A client that is closing is given a moment to go.
        let t0 = Instant::now();
        while lock(&s.state).client.is_some() && t0.elapsed() < GRACE {
            std::thread::sleep(Duration::from_millis(5));
        }
        let (id, reader) = {
            let mut st = lock(&s.state);
            if st.client.is_some() || s.closing.load(Ordering::SeqCst) {
                st.refused += 1;
                drop(st);
                readers.push(std::thread::spawn(move || refuse(stream)));
                continue;
            }
            let Ok(reader) = stream.try_clone() else {
                continue;
            };
            let id = st.next_id;
            st.next_id += 1;
            st.clients += 1;
            st.client = Some(Client {
                id,
                stream,
                joined: false,
            });
            // At a line start the client is greeted now, else at the next one.
            if !st.mid_line {
                if let Some(c) = st.client.as_mut() {
                    c.joined = true;
                }
                let mut hello = Vec::new();
                greet(&mut hello);
                send(&mut st, &hello);
            }
            (id, reader)
        };
        let s = s.clone();
        readers.push(std::thread::spawn(move || client_loop(&s, id, reader)));
    }
    for r in readers {
        let _ = r.join();
    }
}

/// A refused client: the line, then its bytes read and dropped until it closes (at most
/// [`DRAIN`]), so the line is not lost in a reset of the connection.
fn refuse(mut stream: TcpStream) {
    let _ = stream.write_all(format!("{REFUSED}\r\n").as_bytes());
    let _ = stream.shutdown(Shutdown::Write);
    let t0 = Instant::now();
    let mut buf = [0u8; 1024];
    while let Some(left) = DRAIN.checked_sub(t0.elapsed()).filter(|l| !l.is_zero()) {
        let _ = stream.set_read_timeout(Some(left));
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
    }
}

/// Writes `bytes` to the firmware, waiting for QEMU to connect if it has not yet (a client may
/// connect before QEMU has started). False when QEMU's end is gone.
fn to_uart(s: &Shared, bytes: &[u8]) -> bool {
    let mut st = lock(&s.state);
    loop {
        if st.ready {
            if let Some(u) = lock(&s.uart_tx).as_mut() {
                drop(st);
                return u.write_all(bytes).is_ok();
            }
        }
        if st.uart_closed || s.closing.load(Ordering::SeqCst) {
            return false;
        }
        st = s
            .changed
            .wait_timeout(st, Duration::from_millis(100))
            .map(|r| r.0)
            .unwrap_or_else(|e| e.into_inner().0);
    }
}

/// The connected client's bytes to the firmware through the gate, until it disconnects; then
/// its unfinished line is dropped and the port is free.
fn client_loop(s: &Shared, id: u64, mut stream: TcpStream) {
    let mut gate = LineGate::default();
    let mut buf = [0u8; 4096];
    let mut fwd = Vec::new();
    loop {
        let n = match stream.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        if s.closing.load(Ordering::SeqCst) {
            break;
        }
        fwd.clear();
        gate.push(&buf[..n], &mut fwd);
        if !fwd.is_empty() && !to_uart(s, &fwd) {
            break;
        }
    }
    fwd.clear();
    gate.close(&mut fwd);
    if !fwd.is_empty() {
        let _ = to_uart(s, &fwd);
    }
    let mut st = lock(&s.state);
    if st.client.as_ref().is_some_and(|c| c.id == id) {
        st.client = None;
    }
    let _ = stream.shutdown(Shutdown::Both);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A client's bytes wait until the firmware has said its banner, then reach the UART whole
    /// (before, a sender that wrote while QEMU booted lost its first byte).
    #[test]
    fn a_clients_bytes_wait_for_the_firmwares_banner() {
        let (ours, mut theirs) = UnixStream::pair().unwrap();
        let s = Arc::new(Shared {
            state: Mutex::new(State::default()),
            changed: Condvar::new(),
            uart_tx: Mutex::new(Some(ours)),
            closing: AtomicBool::new(false),
        });
        let writer = {
            let s = s.clone();
            std::thread::spawn(move || to_uart(&s, b"G20 G91\n"))
        };
        theirs.set_nonblocking(true).unwrap();
        std::thread::sleep(Duration::from_millis(300));
        let mut buf = [0u8; 64];
        assert!(
            theirs.read(&mut buf).is_err(),
            "bytes reached the UART before the banner"
        );
        let mut banner = String::new();
        millac::protocol::report::write_banner(&mut banner).unwrap();
        output(&mut lock(&s.state), banner.as_bytes());
        s.changed.notify_all();
        assert!(writer.join().unwrap());
        theirs.set_nonblocking(false).unwrap();
        let n = theirs.read(&mut buf).unwrap();
        assert_eq!(&buf[..n], b"G20 G91\n");
    }

    fn through(chunks: &[&[u8]]) -> (Vec<u8>, Vec<u8>) {
        let mut g = LineGate::default();
        let mut out = Vec::new();
        for c in chunks {
            g.push(c, &mut out);
        }
        (out, g.pending().to_vec())
    }

    /// A client that leaves after a lone CR (realtime bytes after it change nothing) gets the
    /// LF the firmware skips; after a CRLF, an LF, a reset or an unfinished line, nothing.
    #[test]
    fn a_lone_cr_is_completed_when_the_client_leaves() {
        for (sent, tail) in [
            (&b"G0 X1\r"[..], &b"\n"[..]),
            (b"G0 X1\r?G0 Y", b"\n"),
            (b"G0 X1\r\n", b""),
            (b"G0 X1\n", b""),
            (b"G0 X1\r\x18", b""),
            (b"G0 X1", b""),
        ] {
            let mut g = LineGate::default();
            let mut out = Vec::new();
            g.push(sent, &mut out);
            let mut end = Vec::new();
            g.close(&mut end);
            assert_eq!(end, tail, "{:?}", String::from_utf8_lossy(sent));
            assert!(g.pending().is_empty());
        }
    }

    /// Lines pass when they end; the unfinished one waits; realtime bytes pass at once, ahead of
    /// the unfinished line's bytes and in place between whole lines.
    #[test]
    fn the_gate_passes_whole_lines_and_realtime_bytes() {
        let (out, pending) = through(&[b"G0 X1\nG1 Y", b"2?", b"\r\nG0 Z"]);
        assert_eq!(out, b"G0 X1\n?G1 Y2\r\n");
        assert_eq!(pending, b"G0 Z");
        // A feed hold inside a line goes at once; the line follows when it ends.
        let (out, pending) = through(&[b"G1 X!5", b"\n"]);
        assert_eq!(out, b"!G1 X5\n");
        assert!(pending.is_empty());
    }

    /// What a disconnect leaves behind: only the unfinished line, which never went out.
    #[test]
    fn an_unfinished_line_never_reaches_the_firmware() {
        let (out, pending) = through(&[b"G0 X1"]);
        assert!(out.is_empty());
        assert_eq!(pending, b"G0 X1");
    }

    /// A soft reset drops the line in progress (the firmware's reset discards it too).
    #[test]
    fn a_reset_drops_the_line_in_progress() {
        let (out, pending) = through(&[b"G0 X1", &[0x18], b"G0 Y1\n"]);
        assert_eq!(out, b"\x18G0 Y1\n");
        assert!(pending.is_empty());
    }

    /// bCNC and CNCjs send extended realtime bytes as UTF-8 (`C2 91`): the pair arrives together.
    #[test]
    fn a_utf8_lead_byte_goes_with_its_realtime_byte() {
        let (out, pending) = through(&[b"G1 X1", &[0xC2], &[0x91], b" Y2\n"]);
        assert_eq!(out, b"\xC2\x91G1 X1 Y2\n");
        assert!(pending.is_empty());
        // Not in front of a realtime byte: it stays in the line.
        let (out, _) = through(&[b"(\xC3\xA9)\n"]);
        assert_eq!(out, b"(\xC3\xA9)\n");
    }

    /// An over-long line is cut to one byte over the limit, enough for the firmware's
    /// `error:11`.
    #[test]
    fn an_over_long_line_is_kept_to_one_byte_over_the_limit() {
        let long = vec![b'X'; LINE_MAX + 50];
        let (out, pending) = through(&[&long, b"\n"]);
        assert_eq!(out.len(), LINE_MAX + 2);
        assert!(out[..LINE_MAX + 1].iter().all(|&b| b == b'X'));
        assert_eq!(out.last(), Some(&b'\n'));
        assert!(pending.is_empty());
    }

    #[test]
    fn the_state_of_a_report() {
        assert_eq!(
            report_state("<Idle|MPos:0.000,0.000,0.000|FS:0,0>"),
            Some("Idle".into())
        );
        assert_eq!(report_state("<Hold:0|MPos:1.000,0,0>"), Some("Hold".into()));
        assert_eq!(report_state("ok"), None);
    }
}
