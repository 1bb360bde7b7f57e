//! `serve` under QEMU (host): the firmware in serial mode with UART0 on a TCP port. A client
//! connects, reads the grbl banner, streams G-code lines and gets one answer per line, polls `?`
//! until the machine is idle, and after the stop the capture ends where the lines programmed.
//! Settings set over the line persist into the next session; a corrupt record starts locked.
use millac_qemu::emulator::serve;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A port no other test of this binary got (the OS may hand a released port out again).
fn free_port() -> u16 {
    static GIVEN: std::sync::Mutex<Vec<u16>> = std::sync::Mutex::new(Vec::new());
    let mut given = GIVEN.lock().unwrap();
    loop {
        let p = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        if !given.contains(&p) {
            given.push(p);
            return p;
        }
    }
}

fn connect(addr: &str) -> TcpStream {
    let t0 = Instant::now();
    loop {
        match TcpStream::connect(addr) {
            Ok(s) => return s,
            Err(e) if t0.elapsed() < Duration::from_secs(120) => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(50));
            }
            Err(e) => panic!("connect {addr}: {e}"),
        }
    }
}

/// Reads lines until one satisfies `done`; returns them all.
fn read_until(r: &mut BufReader<TcpStream>, done: impl Fn(&str) -> bool) -> Vec<String> {
    let mut got = Vec::new();
    loop {
        let mut l = String::new();
        let n = r
            .read_line(&mut l)
            .unwrap_or_else(|e| panic!("read from the serial port: {e}; so far: {got:?}"));
        assert!(n > 0, "serial port closed; so far: {got:?}");
        let l = l.trim_end().to_string();
        let stop = done(&l);
        got.push(l);
        if stop {
            return got;
        }
    }
}

/// `serve` with the simulated cut of a 5 x 3 in steel block (transducer noise `seed`; `ac`: the
/// AC applies its cap, else it measures only) in `out`, connected and past the banner: the stop
/// flag, the server thread and the connection's two ends.
#[allow(clippy::type_complexity)]
fn serve_steel_block(
    out: &std::path::Path,
    seed: u64,
    ac: bool,
) -> (
    Arc<AtomicBool>,
    std::thread::JoinHandle<anyhow::Result<serve::Served>>,
    TcpStream,
    BufReader<TcpStream>,
) {
    use millac_plant::Stock;
    use millac_qemu::emulator::runner::AcRun;
    use millac_qemu::host::acsim::Cut;
    let settings_file = serve::default_settings(out);
    let addr = format!("127.0.0.1:{}", free_port());
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let (out, addr, stop) = (out.to_path_buf(), addr.clone(), stop.clone());
        std::thread::spawn(move || {
            let ac = AcRun {
                cut: Cut::steel(Stock::parse("blank X0 Y0 W5 H3 Z0\n").unwrap(), seed),
                ac,
                faults: Vec::new(),
                settings: millac::ac::AcSettings::default(),
            };
            serve::serve(&out, &settings_file, &addr, 4, Some(&ac), None, stop)
        })
    };
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    (stop, server, w, r)
}

/// The banner the port greets a client with, then a soft reset and the banner after it: the
/// lines up to that second banner's end.
fn banner(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> Vec<String> {
    // The port greets every client with the banner (the firmware's first one may come too, if
    // it starts while we connect); then a soft reset gives the banner the tests read after.
    let greeting = whole_banner(r, Duration::from_secs(120));
    assert!(greeting.is_some(), "no banner on connect");
    w.write_all(&[0x18]).expect("0x18");
    let got = whole_banner(r, Duration::from_secs(120)).expect("no banner after 0x18");
    r.get_ref()
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    got
}

/// Reads lines until a whole banner (`Grbl 1.1...` then `[MSG:millac ...]`) has come, within
/// `limit`; the lines read, or None.
fn whole_banner(r: &mut BufReader<TcpStream>, limit: Duration) -> Option<Vec<String>> {
    r.get_ref()
        .set_read_timeout(Some(Duration::from_secs(2)))
        .unwrap();
    let t0 = Instant::now();
    let mut got = Vec::new();
    // A line cut by the read timeout goes on in the next read (kept across the retries).
    let mut l = String::new();
    while t0.elapsed() < limit {
        match r.read_line(&mut l) {
            Ok(0) => return None,
            Ok(_) => {}
            Err(_) => continue,
        }
        let line = l.trim_end().to_string();
        l.clear();
        let done = line.starts_with("[MSG:millac")
            && got
                .last()
                .is_some_and(|g: &String| g.starts_with("Grbl 1.1"));
        got.push(line);
        if done {
            return Some(got);
        }
    }
    None
}

/// A `serve` session (NC only) on its own port and directory, in a thread until `stop`.
struct Session {
    out: std::path::PathBuf,
    addr: String,
    stop: Arc<AtomicBool>,
    server: std::thread::JoinHandle<anyhow::Result<serve::Served>>,
}

/// The temporary directory of `tag`, emptied.
fn fresh(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("millac-serve-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn start(tag: &str) -> Session {
    let out = fresh(tag);
    let settings = serve::default_settings(&out);
    start_in(out, settings)
}

/// A session in `out` (kept as it is) with the settings file `settings`.
fn start_in(out: std::path::PathBuf, settings: std::path::PathBuf) -> Session {
    start_machine(out, settings, None)
}

/// [`start_in`] with the machine model's limit switches.
fn start_machine(
    out: std::path::PathBuf,
    settings: std::path::PathBuf,
    machine: Option<millac::inputs::LimitSwitches>,
) -> Session {
    let addr = format!("127.0.0.1:{}", free_port());
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let (out, addr, stop) = (out.clone(), addr.clone(), stop.clone());
        std::thread::spawn(move || {
            serve::serve(&out, &settings, &addr, 4, None, machine.as_ref(), stop)
        })
    };
    Session {
        out,
        addr,
        stop,
        server,
    }
}

/// The capture of a session that ran `prog` to its end: the pulse counts match, every block ends
/// exactly on its end point, and the summary's final position is the program's end.
fn check_capture_against(
    prog: &[millac_qemu::analysis::ProgBlock],
    settings: &millac::Settings,
    served: &serve::Served,
) {
    let report = millac_qemu::analysis::analyse(prog, settings, 0, &served.capture.pins);
    assert!(report.counts_match, "pulse counts");
    for (k, b) in report.blocks.iter().enumerate() {
        assert!(
            b.end_exact,
            "block {k} does not end on its end point: {b:?}"
        );
    }
    let p = &served.summary["final_position_blu"];
    let end = prog.last().unwrap().end;
    assert_eq!(
        [p["x"].as_i64(), p["y"].as_i64(), p["z"].as_i64()],
        end.map(|v| Some(i64::from(v)))
    );
}

/// A session with a pty from socat in front of its port, as for any serial-only sender: once the
/// firmware answers on TCP (it may still be starting under load), socat takes the port. The
/// session, the pty's path and the relay (kill it when done).
fn start_with_pty(tag: &str) -> (Session, std::path::PathBuf, std::process::Child) {
    use std::process::{Command, Stdio};
    let socat = millac_qemu::emulator::tools::ensure_tool("socat").expect("socat");
    let session = start(tag);
    let (out, addr) = (&session.out, &session.addr);
    std::fs::create_dir_all(out).unwrap();
    {
        let stream = connect(addr);
        let mut w = stream.try_clone().unwrap();
        let mut r = BufReader::new(stream);
        banner(&mut w, &mut r);
    }
    let tty = out.join("tty");
    let relay = Command::new(socat)
        .arg(format!("pty,raw,echo=0,link={}", tty.display()))
        .arg(format!("tcp:{addr}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("socat");
    let t0 = Instant::now();
    while !tty.exists() {
        assert!(t0.elapsed() < Duration::from_secs(10), "no pty from socat");
        std::thread::sleep(Duration::from_millis(20));
    }
    (session, tty, relay)
}

#[test]
fn a_sender_streams_lines_over_tcp_and_the_capture_ends_where_they_programmed() {
    let Session {
        out,
        addr,
        stop,
        server,
    } = start("lines");
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    let banner = banner(&mut w, &mut r);
    // The settings table answers `$$` (grbl's $0 step pulse in us) and refuses a bad value.
    w.write_all(b"$$\n").unwrap();
    let listing = read_until(&mut r, |s| s == "ok");
    assert!(listing.iter().any(|l| l == "$0=5"), "{listing:?}");
    w.write_all(b"$201=50\n").unwrap();
    assert_eq!(
        read_until(&mut r, |s| s.starts_with("error:") || s == "ok")
            .last()
            .unwrap(),
        "error:52"
    );
    assert!(
        banner.iter().any(|l| l.starts_with("Grbl 1.1")),
        "{banner:?}"
    );
    // One answer per line, in order; a bad line is refused alone.
    let lines = [
        "G20 G91 G1 F30 X0.02",
        "X0.01 Y0.005",
        "G1 X0.01 Q1",
        "",
        "Y-0.001\rX-0.001",
    ];
    let mut answers = Vec::new();
    for l in lines {
        w.write_all(format!("{l}\n").as_bytes()).unwrap();
        let n = l.split('\r').count();
        for _ in 0..n {
            let got = read_until(&mut r, |s| s == "ok" || s.starts_with("error:"));
            answers.push(got.last().unwrap().clone());
        }
    }
    // The Q word no command of the line takes: grbl's unused words, error 36.
    assert_eq!(answers, ["ok", "ok", "error:36", "ok", "ok", "ok"]);
    // `?` until idle (the last line ran after the look-ahead found no next line); the states
    // seen on the way.
    let until_idle = |w: &mut TcpStream, r: &mut BufReader<TcpStream>| {
        let t0 = Instant::now();
        let mut seen = Vec::new();
        loop {
            w.write_all(b"?").unwrap();
            let got = read_until(r, |s| s.starts_with('<'));
            let s = got.last().unwrap().clone();
            if s.starts_with("<Idle") {
                return (s, seen);
            }
            seen.push(s.clone());
            assert!(t0.elapsed() < Duration::from_secs(120), "never idle: {s}");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let (last, _) = until_idle(&mut w, &mut r);
    // 0.029 in = 0.7366 mm, 0.004 in = 0.1016 mm.
    assert!(
        last.starts_with("<Idle|MPos:0.737,0.102,0.000|FS:0,0|"),
        "{last}"
    );
    // A jog of +2.54 mm in X (1000 BLU) at 500 mm/min: `Jog` while it runs, then idle at its end;
    // the parser follows it, so an absolute move afterwards starts from there.
    w.write_all(b"$J=G91 G21 X2.54 F500\n").unwrap();
    assert_eq!(
        read_until(&mut r, |s| s == "ok" || s.starts_with("error:"))
            .last()
            .unwrap(),
        "ok"
    );
    let (last, seen) = until_idle(&mut w, &mut r);
    assert!(seen.iter().all(|s| s.starts_with("<Jog|")), "{seen:?}");
    assert!(last.starts_with("<Idle|MPos:3.277,0.102,0.000|"), "{last}");
    w.write_all(b"G90 G0 Y0\n").unwrap();
    assert_eq!(
        read_until(&mut r, |s| s == "ok" || s.starts_with("error:"))
            .last()
            .unwrap(),
        "ok"
    );
    let (last, _) = until_idle(&mut w, &mut r);
    assert!(last.starts_with("<Idle|MPos:3.277,0.000,0.000|"), "{last}");
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let p = &served.summary["final_position_blu"];
    assert_eq!(
        (p["x"].as_i64(), p["y"].as_i64(), p["z"].as_i64()),
        (Some(1290), Some(0), Some(0))
    );
    assert!(out.join("capture.vcd").exists());
    assert!(served.summary["frames"].as_u64().unwrap() > 0);
    // summary.json as for `run`, from the session replayed from the firmware's log `serve.nc`:
    // the five lines that moved and the jog are its blocks, each ending on its end point, frame
    // for frame the host core's; the pulses per axis are the capture's (0.029 + 0.001 in and the
    // jog's 1000 BLU in X; 0.005 + 0.001 in out and 0.004 in back in Y).
    let s = &served.summary;
    assert_eq!(s["blocks"].as_u64(), Some(6), "{s}");
    assert_eq!(s["end_points_exact"], true, "{s}");
    assert_eq!(s["pulses_match_host"], true, "{s}");
    let mut edges = [0i64; 3];
    for e in millac_qemu::analysis::edges(0, &served.capture.pins).edges {
        edges[e.axis] += 1;
    }
    assert_eq!(edges, [1310, 100, 0]);
    assert_eq!(
        [&s["pulses"]["x"], &s["pulses"]["y"], &s["pulses"]["z"]].map(|v| v.as_i64()),
        edges.map(Some)
    );
    let log = std::fs::read_to_string(out.join("serve.nc")).unwrap();
    assert!(log.contains("(millac:jog G91 G21 X2.54 F500)\n"), "{log}");
}

/// The socat pty bridge that serial-only senders use (docs/user/senders.md): the pty,
/// opened as a plain file, gets the banner after 0x18, a status report for `?` and the build info
/// for `$I`.
#[test]
fn a_pty_from_socat_speaks_grbl() {
    use std::sync::mpsc;
    let (Session { stop, server, .. }, tty, mut relay) = start_with_pty("pty");
    let mut pty = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&tty)
        .expect("open the pty");
    let (tx, rx) = mpsc::channel();
    let reader = BufReader::new(pty.try_clone().unwrap());
    std::thread::spawn(move || {
        for l in reader.lines() {
            let Ok(l) = l else { break };
            if tx.send(l.trim_end().to_string()).is_err() {
                break;
            }
        }
    });
    let until = |done: &dyn Fn(&str) -> bool| {
        let mut got = Vec::new();
        loop {
            let l = rx
                .recv_timeout(Duration::from_secs(30))
                .unwrap_or_else(|e| panic!("{e}; so far: {got:?}"));
            let stop = done(&l);
            got.push(l);
            if stop {
                return got;
            }
        }
    };
    pty.write_all(&[0x18]).unwrap();
    let banner = until(&|s| s.starts_with("[MSG:millac"));
    assert!(
        banner.iter().any(|l| l.starts_with("Grbl 1.1h")),
        "{banner:?}"
    );
    pty.write_all(b"?").unwrap();
    let status = until(&|s| s.starts_with('<'));
    assert!(
        status
            .last()
            .unwrap()
            .starts_with("<Idle|MPos:0.000,0.000,0.000|"),
        "{status:?}"
    );
    pty.write_all(b"$I\n").unwrap();
    let got = until(&|s| s == "ok" || s.starts_with("error:"));
    // Two banners come, the port's greeting to socat's connection and the firmware's after the
    // 0x18, and the report for `?` (a realtime byte, answered at once) may come between them:
    // the second banner may come here (seen once in a CI run).
    let banner_line =
        |l: &String| l.is_empty() || l.starts_with("Grbl 1.1h") || l.starts_with("[MSG:millac");
    let info: Vec<&str> = got
        .iter()
        .skip_while(|l| banner_line(l))
        .map(String::as_str)
        .collect();
    assert_eq!(info[0], "[VER:1.1h.millac:]", "{got:?}");
    assert!(info[1].starts_with("[OPT:V,15,128"), "{info:?}");
    assert_eq!(info.last(), Some(&"ok"), "{got:?}");
    drop(pty);
    let _ = relay.kill();
    let _ = relay.wait();
    stop.store(true, Ordering::SeqCst);
    server.join().unwrap().expect("serve");
}

/// A real third-party sender, pygrbl-streamer 1.0.5 (PyPI), streams the Fig. 1 program with
/// character counting to `serve` through a pty (socat in front of the TCP port, as for any
/// serial-only sender). While it streams, its `realtime` API polls `?` at 5 Hz, its `pause` /
/// `resume` hold the feed mid-program (`Hold:0` with the position standing still, then the same
/// block goes on) and the feed override goes to 120 % and back. It waits for Idle, and the
/// capture's blocks end exactly on the program's end points.
#[test]
fn pygrbl_streamer_streams_the_fig1_program() {
    use millac::Settings;
    use millac_qemu::{analysis, emulator::tools};
    use std::process::Command;
    let ws = millac_qemu::emulator::firmware::workspace();
    let python = tools::ensure_python_sender(&ws.join("target").join("py-sender")).expect("sender");
    let (Session { stop, server, .. }, tty, mut relay) = start_with_pty("py");
    let program = ws.join("qemu").join("programs").join("fig1-cavity.nc");
    let script = r#"
import sys, threading, time, json
from pygrbl_streamer import GrblStreamer
reports = []
class Sender(GrblStreamer):
    def receive_callback(self, line):
        if line.startswith('<'):
            reports.append(line)
g = Sender(sys.argv[1], auto_unlock=False)
g.connect()
# The sender's write timeout is 1 s, made for a real serial port. Here the port is a pty in front
# of socat, TCP and QEMU, and the test binary runs other QEMU sessions beside this one on two
# cores: a write may wait seconds. CI saw this test fail twice with a write timeout, once as
# SerialTimeoutException from a '?', once as send_file giving up. A real stall still fails: the
# ack, completion and poll timeouts below.
g.serial.write_timeout = 30
result = {}
# A line is acknowledged once its blocks fit the queue (as in grbl), so an ack can wait for the
# longest block of the program: far beyond the sender's default of 30 s on a loaded machine.
job = threading.Thread(target=lambda: result.setdefault('ok', g.send_file(sys.argv[2], completion_timeout=600, ack_timeout=600)))
job.start()
def poll(pred, timeout):
    # '?' at 5 Hz until the newest report satisfies pred
    t0 = time.time()
    while time.time() - t0 < timeout:
        g.realtime(b'?')
        time.sleep(0.2)
        if reports and pred(reports[-1]):
            return reports[-1]
    return None
obs = {'run': poll(lambda s: s.startswith('<Run'), 120)}
poll(lambda s: False, 2.0)
g.pause()
obs['stopped'] = poll(lambda s: s.startswith('<Hold:0'), 30)
n = len(reports)
# At least three reports while held (a second of polls gives five on an idle machine; CI, loaded,
# saw two).
poll(lambda s: len(reports) >= n + 3, 30)
obs['held'] = reports[n:]
g.resume()
g.realtime(b'\x91')
g.realtime(b'\x91')
obs['over'] = poll(lambda s: s.startswith('<Run') and 'Ov:120,' in s, 30)
poll(lambda s: False, 1.0)
g.realtime(b'\x90')
obs['back'] = poll(lambda s: 'Ov:100,' in s, 30)
while job.is_alive():
    poll(lambda s: True, 0.2)
job.join()
obs['ok'] = result.get('ok')
obs['states'] = sorted(set(r[1:].split('|')[0] for r in reports))
obs['last'] = g.last_status.get('raw')
g.disconnect()
print(json.dumps(obs))
"#;
    let sender = Command::new(&python)
        .args(["-c", script])
        .arg(&tty)
        .arg(&program)
        .output()
        .expect("run the sender");
    let _ = relay.kill();
    let _ = relay.wait();
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let said = String::from_utf8_lossy(&sender.stdout);
    assert!(
        sender.status.success(),
        "sender failed: {said}{}",
        String::from_utf8_lossy(&sender.stderr)
    );
    let obs: serde_json::Value = serde_json::from_str(said.trim()).expect("the sender's JSON");
    eprintln!("sender saw: {obs:#}");
    assert_eq!(obs["ok"], true, "{obs:#}");
    assert!(
        obs["last"]
            .as_str()
            .unwrap()
            .starts_with("<Idle|MPos:0.000,0.000,2.540"),
        "{obs:#}"
    );
    // The hold stopped the machine mid-program and it stood still until the resume.
    let mpos = |s: &str| s.split('|').nth(1).unwrap_or("").to_string();
    let stopped = obs["stopped"].as_str().expect("Hold:0 after pause");
    let held: Vec<&str> = obs["held"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(held.len() >= 3, "{obs:#}");
    for h in &held {
        assert!(h.starts_with("<Hold:0|"), "{obs:#}");
        assert_eq!(mpos(h), mpos(stopped), "moved during the hold: {obs:#}");
    }
    assert_ne!(
        mpos(stopped),
        "MPos:0.000,0.000,2.540",
        "held at the end? {obs:#}"
    );
    assert!(obs["over"].is_string(), "no Run at 120 %: {obs:#}");
    assert!(
        obs["back"].is_string(),
        "override not back at 100 %: {obs:#}"
    );
    let states: Vec<&str> = obs["states"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(
        states.contains(&"Run") && states.contains(&"Hold:0"),
        "{states:?}"
    );
    let settings = Settings::default();
    let text = std::fs::read_to_string(&program).unwrap();
    let prog = analysis::load_program(&text, &settings).unwrap();
    check_capture_against(&prog, &settings, &served);
}

/// The real bCNC (PyPI 0.9.16, its own Sender, G-code compiler and grbl 1.1 controller, driven
/// headless by `qemu/senders/bcnc_stream.py`) streams a job to `serve` over TCP and moves the feed
/// override the way its slider does: its `overrideSet()` writes `chr(0x91)` UTF-8 encoded, `C2 91`
/// on the wire, and `C2 90` to go back (grbl 1.1 drops the `C2`). The job runs to its end: no
/// error, the override seen in the status reports (at least 110 %, bCNC steps from the last Ov:
/// it saw) and back at 100 %, Idle at the end, and the capture ends every block on its end point.
/// After the job bCNC sends `!` and a soft reset, as it does on every job end. Before the RX
/// path dropped the `C2`, the line after it got `error:1` and bCNC stopped the job.
#[test]
fn bcnc_streams_a_job_with_its_feed_override_to_the_end() {
    use millac::Settings;
    use millac_qemu::{analysis, emulator::tools};
    use std::process::Command;
    let ws = millac_qemu::emulator::firmware::workspace();
    let python = tools::ensure_bcnc(&ws.join("target").join("bcnc")).expect("bCNC");
    let Session {
        out,
        addr,
        stop,
        server,
    } = start("bcnc");
    // Wait until the firmware answers (bCNC flushes the banner and would not wait for it).
    {
        let stream = connect(&addr);
        let mut w = stream.try_clone().unwrap();
        let mut r = BufReader::new(stream);
        banner(&mut w, &mut r);
    }
    std::fs::create_dir_all(&out).unwrap();
    let program = out.join("square.nc");
    let text = "G20 G90 G17\nG0 X0.5 Y0.5\nG1 X2 F30\nG1 Y2\nG1 X0.5\nG1 Y0.5\nG0 X0 Y0\nM2\n";
    std::fs::write(&program, text).unwrap();
    let sender = Command::new(&python)
        .arg(ws.join("qemu").join("senders").join("bcnc_stream.py"))
        .arg(&addr)
        .arg(&program)
        .args(["--override-at", "2", "--override", "110"])
        .args(["--override-back-at", "6", "--timeout", "600"])
        .output()
        .expect("run bCNC");
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let said = String::from_utf8_lossy(&sender.stdout);
    let log = String::from_utf8_lossy(&sender.stderr);
    assert!(sender.status.success(), "bCNC failed: {said}\n{log}");
    let obs: serde_json::Value = serde_json::from_str(said.trim()).expect("bCNC's JSON");
    eprintln!("bCNC saw: {obs:#}");
    assert_eq!(obs["ok"], true, "{obs:#}");
    assert_eq!(obs["errors"].as_array().map(Vec::len), Some(0), "{obs:#}");
    let ov: Vec<u32> = obs["ov_reports"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|r| {
            let r = r["report"].as_str()?;
            r.split("Ov:").nth(1)?.split(',').next()?.parse().ok()
        })
        .collect();
    assert!(
        ov.iter().any(|&f| f >= 110),
        "the override never took: {ov:?}"
    );
    assert_eq!(ov.last(), Some(&100), "not back at 100 %: {ov:?}");
    assert!(
        obs["last_report"]
            .as_str()
            .unwrap_or("")
            .starts_with("<Idle"),
        "{obs:#}"
    );
    let settings = Settings::default();
    let prog = analysis::load_program(text, &settings).unwrap();
    check_capture_against(&prog, &settings, &served);
}

/// Sends `line` and reads to its `ok` / `error:N`; every line read.
fn ask(w: &mut TcpStream, r: &mut BufReader<TcpStream>, line: &str) -> Vec<String> {
    w.write_all(format!("{line}\n").as_bytes()).unwrap();
    read_until(r, |s| s == "ok" || s.starts_with("error:"))
}

/// `$$` as the firmware lists it (its `$N=value` lines).
fn listing(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> Vec<String> {
    let got = ask(w, r, "$$");
    assert_eq!(got.last().unwrap(), "ok", "{got:?}");
    got.into_iter().filter(|l| l.starts_with('$')).collect()
}

/// `$$` of `m` as the core's table lists it.
fn expected_listing(m: &millac::protocol::table::MachineSettings) -> Vec<String> {
    let mut s = String::new();
    m.list(&mut s).unwrap();
    s.lines().map(str::to_string).collect()
}

/// The first status report's state.
fn state(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> String {
    w.write_all(b"?").unwrap();
    let s = read_until(r, |s| s.starts_with('<')).pop().unwrap();
    s.trim_start_matches('<')
        .split('|')
        .next()
        .unwrap()
        .to_string()
}

/// `$0=7` (step pulse 7 us) and a tool described with `$T3=...` set in one session are written to
/// the settings file (kept outside the session's directory, so `serve` links it) and the next
/// session, in a fresh directory with the same file, starts with them: no alarm, `$$` and `$T3`
/// list them, and the frame runs with it (the capture's pulses are 7 us wide, 5 us by default).
#[test]
fn a_setting_persists_into_the_next_session() {
    use millac::protocol::table::{record, MachineSettings};
    let settings = fresh("state").join("settings.bin");
    let mut want = MachineSettings::default();
    want.set_line("$0=7").unwrap();
    let tool_line = "$T3=L45.2 D6 N4 K1 F900 M12.5 (ball end mill)";
    millac::protocol::SettingsTable::tool(&mut want, "3=L45.2D6N4K1F900M12.5", &mut String::new())
        .unwrap();
    {
        let Session {
            addr, stop, server, ..
        } = start_in(fresh("persist1"), settings.clone());
        let stream = connect(&addr);
        let mut w = stream.try_clone().unwrap();
        let mut r = BufReader::new(stream);
        banner(&mut w, &mut r);
        assert_eq!(ask(&mut w, &mut r, "$0=7").last().unwrap(), "ok");
        let t = ask(&mut w, &mut r, "$t3 = l45.2 d6 n4 k1 f900 m12.5");
        assert_eq!(t.last().unwrap(), "ok", "{t:?}");
        stop.store(true, Ordering::SeqCst);
        server.join().unwrap().expect("serve");
    }
    let bytes = std::fs::read(&settings).expect("the settings file");
    assert_eq!(
        record::decode(&bytes, &millac::settings::BoardLimits::GENERIC)
            .map(millac::settings::Valid::get),
        Ok(want)
    );
    let Session {
        addr, stop, server, ..
    } = start_in(fresh("persist2"), settings.clone());
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    let b = banner(&mut w, &mut r);
    assert!(!b.iter().any(|l| l.starts_with("ALARM")), "{b:?}");
    assert_eq!(listing(&mut w, &mut r), expected_listing(&want));
    assert_eq!(ask(&mut w, &mut r, "$T3"), [tool_line, "ok"]);
    assert_eq!(state(&mut w, &mut r), "Idle");
    assert_eq!(
        ask(&mut w, &mut r, "G91 G1 F30 X0.01").last().unwrap(),
        "ok"
    );
    let t0 = Instant::now();
    while state(&mut w, &mut r) != "Idle" || t0.elapsed() < Duration::from_millis(200) {
        assert!(t0.elapsed() < Duration::from_secs(60), "never idle");
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let e = millac_qemu::analysis::edges(0, &served.capture.pins);
    assert_eq!(e.edges.len(), 100, "0.01 in = 100 BLU");
    let width = e.min_pulse_width_ns.unwrap();
    assert!((7000..7000 + 2000).contains(&width), "{width} ns");
}

/// Homing under QEMU through `serve`, with the lines the senders' Homing and Unlock buttons send
/// (`$H`, `$X`): the machine model stands 5, 4 and 3 mm short of its switches. A first session
/// turns homing on (`$22=1`, quick pull-off and pauses) and homes; the second, on the same
/// settings file, starts locked (`ALARM:11`: G-code and `$X` refused), homes with `$H` and is
/// Idle at the home position: the soft maxima less the 0.2 mm pull-off.
#[test]
fn a_machine_homes_through_serve_and_starts_locked_until_it_has() {
    let settings = fresh("homing-state").join("settings.bin");
    let machine = millac::inputs::LimitSwitches {
        start: [-1_969, -1_575, -1_181],
        at: [0; 3],
        negative: 0,
        probe: None,
        setter: None,
        tools: [0; millac::inputs::TOOLS],
    };
    let home = "MPos:253.799,253.799,101.399";
    {
        let Session {
            addr, stop, server, ..
        } = start_machine(fresh("homing1"), settings.clone(), Some(machine));
        let stream = connect(&addr);
        let mut w = stream.try_clone().unwrap();
        let mut r = BufReader::new(stream);
        banner(&mut w, &mut r);
        for set in ["$22=1", "$27=0.2", "$24=100", "$26=20"] {
            assert_eq!(ask(&mut w, &mut r, set).last().unwrap(), "ok", "{set}");
        }
        let got = ask(&mut w, &mut r, "$H");
        assert_eq!(got.last().unwrap(), "ok", "{got:?}");
        w.write_all(b"?").unwrap();
        let s = read_until(&mut r, |s| s.starts_with('<')).pop().unwrap();
        assert!(s.starts_with("<Idle|") && s.contains(home), "{s}");
        stop.store(true, Ordering::SeqCst);
        server.join().unwrap().expect("serve");
    }
    let Session {
        addr, stop, server, ..
    } = start_machine(fresh("homing2"), settings, Some(machine));
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    let mut b = banner(&mut w, &mut r);
    // The firmware's power-up lines may come after the port's greeting: read on to G0's answer.
    b.extend(ask(&mut w, &mut r, "G0 X1"));
    assert_eq!(b.last().unwrap(), "error:9", "{b:?}");
    assert!(b.iter().any(|l| l == "ALARM:11"), "{b:?}");
    assert_eq!(state(&mut w, &mut r), "Alarm");
    assert_eq!(
        ask(&mut w, &mut r, "$X"),
        ["[MSG:Homing required: '$H']", "error:9"]
    );
    assert_eq!(ask(&mut w, &mut r, "$H").last().unwrap(), "ok");
    w.write_all(b"?").unwrap();
    let s = read_until(&mut r, |s| s.starts_with('<')).pop().unwrap();
    assert!(s.starts_with("<Idle|") && s.contains(home), "{s}");
    stop.store(true, Ordering::SeqCst);
    server.join().unwrap().expect("serve");
}

/// Probing under QEMU through `serve`, with the lines CNCjs's probe widget sends for a Z probe
/// on a 10 mm plate (G91, G38.2 Z-10 F20, G90, G10 L20 P1 Z10, G91, G0 Z4, G90): the machine
/// model's plate is 1 mm (394 BLU) below the tool; the probe stops there at once and says so
/// before its `ok`, and G54's Z is set 10 mm below the touch.
#[test]
fn a_z_probe_through_serve_sets_work_zero_as_cncjs_does() {
    let machine = millac::inputs::LimitSwitches {
        start: [0; 3],
        at: [500_000; 3],
        negative: 0,
        probe: Some(-394),
        setter: None,
        tools: [0; millac::inputs::TOOLS],
    };
    let Session {
        addr, stop, server, ..
    } = start_machine(
        fresh("probe"),
        fresh("probe-state").join("settings.bin"),
        Some(machine),
    );
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    assert_eq!(ask(&mut w, &mut r, "G21").last().unwrap(), "ok");
    let mut got = Vec::new();
    for line in [
        "G91",
        "G38.2 Z-10 F20",
        "G90",
        "G10 L20 P1 Z10",
        "G91",
        "G0 Z4",
        "G90",
    ] {
        let a = ask(&mut w, &mut r, line);
        assert_eq!(a.last().unwrap(), "ok", "{line}: {a:?}");
        got.extend(a);
    }
    assert!(
        got.contains(&"[PRB:0.000,0.000,-1.001:1]".to_string()),
        "{got:?}"
    );
    poll_idle(&mut w, &mut r);
    let offsets = ask(&mut w, &mut r, "$#");
    assert!(
        offsets.contains(&"[G54:0.000,0.000,-11.001]".to_string()),
        "{offsets:?}"
    );
    assert!(
        offsets.contains(&"[PRB:0.000,0.000,-1.001:1]".to_string()),
        "{offsets:?}"
    );
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    // The pulses: down 394 BLU to the plate, then up 4 mm.
    let e = millac_qemu::analysis::edges(0, &served.capture.pins);
    assert_eq!(e.edges.len(), 394 + 1575, "Z pulses");
    // The probe cut its move short: the report says so instead of a pulse mismatch, and the
    // session's end is where the machine stands.
    let s = &served.summary;
    assert_eq!(s["replay"]["whole"], false, "{s}");
    assert!(s["pulses_match_host"].is_null(), "{s}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["final_position_blu"]["z"], -394 + 1575, "{s}");
}

/// A settings file with one flipped byte: the banner is followed by `ALARM:120` and why, G-code
/// is locked and the state is Alarm; `$X` unlocks and `$$` lists the defaults, not the record's
/// values; the file is left as it was.
#[test]
fn a_corrupt_settings_record_starts_locked_on_the_defaults() {
    use millac::protocol::codes::alarm::SETTINGS_DEFAULTS;
    use millac::protocol::table::{record, MachineSettings};
    let out = fresh("corrupt");
    std::fs::create_dir_all(&out).unwrap();
    let mut m = MachineSettings::default();
    m.set_line("$0=7").unwrap();
    let mut bytes = record::encode(&m).to_vec();
    bytes[20] ^= 0x10;
    let file = serve::default_settings(&out);
    std::fs::write(&file, &bytes).unwrap();
    let Session {
        addr, stop, server, ..
    } = start_in(out, file.clone());
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    let told = read_until(&mut r, |s| s.starts_with("[MSG:'$H'|'$X'"));
    assert_eq!(
        told[..2],
        [
            format!("ALARM:{SETTINGS_DEFAULTS}"),
            "[MSG:settings record checksum mismatch; defaults loaded]".to_string()
        ],
        "{told:?}"
    );
    assert_eq!(state(&mut w, &mut r), "Alarm");
    assert_eq!(
        ask(&mut w, &mut r, "G91 G1 F30 X0.01").last().unwrap(),
        "error:9"
    );
    let unlock = ask(&mut w, &mut r, "$X");
    assert_eq!(unlock, ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(state(&mut w, &mut r), "Idle");
    assert_eq!(
        listing(&mut w, &mut r),
        expected_listing(&MachineSettings::default())
    );
    stop.store(true, Ordering::SeqCst);
    server.join().unwrap().expect("serve");
    assert_eq!(std::fs::read(&file).unwrap(), bytes, "load never writes");
}

/// Writes `line`, returns its answer (`ok` or `error:N`), keeping every other line seen in `seen`.
fn send_line(
    w: &mut TcpStream,
    r: &mut BufReader<TcpStream>,
    line: &str,
    seen: &mut Vec<String>,
) -> String {
    w.write_all(format!("{line}\n").as_bytes()).unwrap();
    let got = read_until(r, |s| s == "ok" || s.starts_with("error:"));
    let answer = got.last().unwrap().clone();
    seen.extend(got);
    answer
}

/// `?` until the report satisfies `done`; the reports on the way (the last one is `done`'s).
fn poll_until(
    w: &mut TcpStream,
    r: &mut BufReader<TcpStream>,
    seen: &mut Vec<String>,
    done: impl Fn(&str) -> bool,
) -> Vec<String> {
    let t0 = Instant::now();
    let mut reports = Vec::new();
    loop {
        w.write_all(b"?").unwrap();
        let got = read_until(r, |s| s.starts_with('<'));
        let report = got.last().unwrap().clone();
        seen.extend(got);
        reports.push(report.clone());
        if done(&report) {
            return reports;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "waited for too long; last {report}; seen {seen:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Feed hold and resume under the AC against the simulated cut, and the resume of an AC hold in
/// `serve` (issue 7): a full-depth entry at F30 into steel overloads (issue 6's program); the
/// firmware holds with `[MSG:AC hold: overload ...]`, reports `Hold` with the AC field's
/// `hold:100`, and `~` resumes the AC from f_min: the cut goes on (holding again and resuming
/// as often as it must). An operator's `!` in the cut stops with the position standing still,
/// `~` goes on. At the end the capture's blocks end exactly on the program's end points and the
/// position is exact; ac.log has the hold.
#[test]
fn ac_holds_and_operator_holds_resume_in_the_cut() {
    use millac::Settings;
    use millac_qemu::analysis;
    let out = fresh("ac");
    let (stop, server, mut w, mut r) = serve_steel_block(&out, 7, true);
    let program = "G20 G90\nG0 X-1 Y1.5\nG0 Z-0.3\nG1 X1 F30\nG0 Z0.1\n";
    let mut seen = Vec::new();
    for line in program.lines() {
        assert_eq!(send_line(&mut w, &mut r, line, &mut seen), "ok", "{line}");
    }
    // The overload hold: said once, the state Hold with the AC's alarm number, standing still.
    let reports = poll_until(&mut w, &mut r, &mut seen, |s| s.starts_with("<Hold:0"));
    let msg = seen
        .iter()
        .find(|l| l.starts_with("[MSG:AC hold:"))
        .unwrap_or_else(|| panic!("no AC hold message: {seen:?}"));
    assert!(msg.contains("overload"), "{msg}");
    let held = reports.last().unwrap().clone();
    assert!(
        held.contains(",hold:100>") || held.contains(",hold:100|"),
        "{held}"
    );
    let mpos = |s: &str| s.split('|').nth(1).unwrap_or("").to_string();
    for _ in 0..3 {
        let again = poll_until(&mut w, &mut r, &mut seen, |_| true);
        assert_eq!(
            mpos(again.last().unwrap()),
            mpos(&held),
            "moved in the hold"
        );
    }
    // `~`: the AC resumes from f_min and the cut goes on; an operator hold in it. The resumed
    // cut may overload and hold again before a report shows it running (CI saw it once: the
    // poll waited 300 s on a second hold): resumed again, as the loop at the end does.
    w.write_all(b"~").unwrap();
    let resumed = Instant::now();
    loop {
        assert!(
            resumed.elapsed() < Duration::from_secs(300),
            "never ran again: {seen:?}"
        );
        let rep = poll_until(&mut w, &mut r, &mut seen, |s| {
            (s.starts_with("<Run") && s.contains(",run>")) || s.starts_with("<Hold:0")
        });
        if rep.last().unwrap().starts_with("<Run") {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
        w.write_all(b"~").unwrap();
    }
    std::thread::sleep(Duration::from_millis(300));
    w.write_all(b"!").unwrap();
    let stopped = poll_until(&mut w, &mut r, &mut seen, |s| s.starts_with("<Hold:0"));
    let at = mpos(stopped.last().unwrap());
    std::thread::sleep(Duration::from_millis(500));
    let still = poll_until(&mut w, &mut r, &mut seen, |_| true);
    assert_eq!(
        mpos(still.last().unwrap()),
        at,
        "moved in the operator's hold"
    );
    w.write_all(b"~").unwrap();
    // To the end, resuming any further AC hold.
    let t0 = Instant::now();
    let mut resumes = 1;
    loop {
        let rep = poll_until(&mut w, &mut r, &mut seen, |_| true);
        let s = rep.last().unwrap();
        if s.starts_with("<Idle") {
            break;
        }
        if s.starts_with("<Hold:0") {
            w.write_all(b"~").unwrap();
            resumes += 1;
        }
        assert!(t0.elapsed() < Duration::from_secs(300), "{s}");
        std::thread::sleep(Duration::from_millis(100));
    }
    eprintln!(
        "AC serve session: {resumes} resumes, hold at {}",
        mpos(&held)
    );
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let settings = Settings::default();
    let prog = analysis::load_program(&format!("{program}M2\n"), &settings).unwrap();
    check_capture_against(&prog, &settings, &served);
    let log = std::fs::read_to_string(out.join("ac.log")).unwrap();
    assert!(log.contains("hold:"), "no hold in ac.log");
}

/// Polls `?` until the machine reports Idle; the report.
fn poll_idle(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> String {
    let t0 = Instant::now();
    loop {
        w.write_all(b"?").unwrap();
        let got = read_until(r, |s| s.starts_with('<'));
        let s = got.last().unwrap().clone();
        if s.starts_with("<Idle") {
            return s;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "never idle: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The free ring bytes of a status report with `$10=3` (`Bf:blocks,bytes`).
fn ring_free(report: &str) -> usize {
    let bf = report
        .split('|')
        .find_map(|f| f.strip_prefix("Bf:"))
        .unwrap_or_else(|| panic!("no Bf: in {report}"));
    bf.split(',').nth(1).unwrap().parse().unwrap()
}

/// The receive overflow message: the bytes lost.
fn lost_bytes(msg: &str) -> Option<u64> {
    msg.strip_prefix("[MSG:receive overflow: ")?
        .strip_suffix(" bytes lost]")?
        .parse()
        .ok()
}

/// A client that ignores flow control writes 300 lines of 16 bytes at once. What happens: the
/// 128-byte ring takes an unbroken prefix and refuses bytes until the loader has drained it,
/// again and again while the flood lasts; each loss raises `ALARM:110` with the bytes lost, the
/// line it damaged gets `error:11`, the lines after it `error:9` (alarm lock). The contract
/// asserted: the replies, read as a stream, follow exactly that (every line answered `ok` comes
/// before the first loss; one `error:11` per loss, right after its alarm; nothing else); one
/// reply per line whose line end was received (the lines lost with the refused bytes, bounded by
/// the alarms' byte counts, get none); every line answered `ok` ran and nothing else did (the
/// capture's pulses and the final position are those of exactly the `ok` lines); then a soft reset
/// and `$X` recover the machine and it streams normally. Last, a flood followed at once by a soft
/// reset and `$X` (a sender recovering from its own overflow): the `$X` is answered, or its loss
/// reported, never dropped silently. The session's summary.json (from the firmware's log
/// `serve.nc`) has the keys of a `run` of that log and the same blocks, pulses and position.
#[test]
fn a_flood_is_refused_in_step_and_every_line_answered_ok_ran() {
    let Session {
        out,
        addr,
        stop,
        server,
    } = start("flood");
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    // `$10=3`: the status reports carry `Bf:` (free ring bytes).
    assert_eq!(ask(&mut w, &mut r, "$10=3").last().unwrap(), "ok");
    assert_eq!(ask(&mut w, &mut r, "G20 G91 G1 F30").last().unwrap(), "ok");
    // The flood starts on an idle machine with an empty ring. (Without this pause, 2 of about 25
    // runs got no `ok` at all: QEMU's PL011 takes bytes as fast as the guest reads them, with no
    // baud rate, so the RX interrupt (priority 2) can take the whole burst while the loader
    // (idle, priority 0) gets no turn: the ring fills with the first 128 bytes and refuses the
    // rest before a single line is read. That is a correct answer to a flood (errors, nothing
    // accepted lost) but not the mix this test wants to see; at 115 200 baud a real board reads
    // a byte every 87 us and the loader runs in between. Reproduced with a plain TCP client
    // against `serve`, 1 run in 4.)
    std::thread::sleep(Duration::from_millis(300));
    w.write_all(b"?").unwrap();
    let report = read_until(&mut r, |s| s.starts_with('<'));
    assert!(
        report.last().unwrap().starts_with("<Idle|") && ring_free(report.last().unwrap()) == 128,
        "{report:?}"
    );
    // Line i moves X by 1 BLU and Y by i % 7 + 1 BLU (0.0001 in): 16 bytes a line.
    let step = |i: usize| (1i64, (i % 7 + 1) as i64);
    const N: usize = 300;
    const LEN: u64 = 16;
    let flood: String = (0..N)
        .map(|i| format!("X0.0001 Y0.000{}\n", step(i).1))
        .collect();
    assert_eq!(flood.len() as u64, N as u64 * LEN);
    w.write_all(flood.as_bytes()).unwrap();
    // `?` comes after the flood in the stream, so a report with 128 free ring bytes comes after
    // every flood byte was stored (and processed) or refused. A loss at the very end is reported
    // just after that report: one more `?` after a pause takes it in.
    let mut said = Vec::new();
    let t0 = Instant::now();
    loop {
        w.write_all(b"?").unwrap();
        let mut got = read_until(&mut r, |s| s.starts_with('<'));
        let report = got.pop().unwrap();
        said.extend(got);
        if ring_free(&report) == 128 {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "ring never drained");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    w.write_all(b"?").unwrap();
    let mut got = read_until(&mut r, |s| s.starts_with('<'));
    let report = got.pop().unwrap();
    said.extend(got);
    assert!(report.starts_with("<Alarm|"), "{report}");
    // The replies as a stream: `ok` until the first loss; each loss `ALARM:110`, its message and
    // then (when its line ends) `error:11`; after the first loss `error:9` for whole lines.
    let (mut oks, mut replies, mut losses, mut damaged) = (0usize, 0usize, Vec::new(), false);
    let mut it = said.iter();
    while let Some(l) = it.next() {
        match l.as_str() {
            "ALARM:110" => {
                let msg = it.next().map(String::as_str).unwrap_or("");
                losses.push(lost_bytes(msg).unwrap_or_else(|| panic!("{msg:?}: {said:?}")));
                damaged = true;
            }
            "ok" | "error:11" | "error:9" => {
                let want = match (damaged, losses.is_empty()) {
                    (true, _) => "error:11",
                    (false, true) => "ok",
                    (false, false) => "error:9",
                };
                assert_eq!(l, want, "reply {replies}: {said:?}");
                oks += usize::from(l == "ok");
                replies += 1;
                damaged = false;
            }
            _ => panic!("unexpected {l:?}: {said:?}"),
        }
    }
    assert!(!losses.is_empty(), "the flood was never refused: {said:?}");
    assert!((8..N).contains(&oks), "{oks} lines ran: {said:?}");
    // One reply per line whose end was received: the line ends lost lie within the refused bytes.
    let ends_lost = (N - replies) as u64;
    let lo: u64 = losses.iter().map(|l| l / LEN).sum();
    let hi: u64 = losses.iter().map(|l| l.div_ceil(LEN)).sum();
    assert!(
        (lo..=hi).contains(&ends_lost),
        "{replies} replies to {N} lines, bytes lost {losses:?}"
    );
    // Recovery: a soft reset (the lock stays), `$X`, and the modes again; then streaming with a
    // reply awaited per line, every line `ok`.
    w.write_all(&[0x18]).unwrap();
    read_until(&mut r, |s| s == "[MSG:'$H'|'$X' to unlock]");
    let unlock = ask(&mut w, &mut r, "$X");
    assert_eq!(unlock, ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(ask(&mut w, &mut r, "G20 G91 G1 F30").last().unwrap(), "ok");
    let after: Vec<(i64, i64)> = (0..20).map(|i| (2, -(i % 3 + 1))).collect();
    for (x, y) in &after {
        let line = format!("X0.000{x} Y-0.000{}", -y);
        assert_eq!(ask(&mut w, &mut r, &line).last().unwrap(), "ok", "{line}");
    }
    let ran: Vec<(i64, i64)> = (0..oks).map(step).chain(after.iter().copied()).collect();
    let end = ran.iter().fold((0, 0), |a, m| (a.0 + m.0, a.1 + m.1));
    let idle = poll_idle(&mut w, &mut r);
    let mm = |blu: i64| format!("{:.3}", blu as f64 * 0.00254);
    assert!(
        idle.starts_with(&format!("<Idle|MPos:{},{},0.000|", mm(end.0), mm(end.1))),
        "{idle}, expected {end:?} BLU"
    );
    // A flood followed at once by a soft reset and `$X`: comment lines, nothing moves.
    let flood2 = "(flood)\n".repeat(N);
    w.write_all(format!("{flood2}\x18$X\n").as_bytes()).unwrap();
    r.get_ref()
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    read_until(&mut r, |s| s.starts_with("[MSG:millac"));
    let answer = read_until(&mut r, |s| {
        s == "ok" || s.starts_with("[MSG:receive overflow")
    });
    if answer.last().unwrap() != "ok" {
        // "$X" (or its start) was refused after the reset: reported; reset and unlock again.
        w.write_all(&[0x18]).unwrap();
        read_until(&mut r, |s| s == "[MSG:'$H'|'$X' to unlock]");
        assert_eq!(ask(&mut w, &mut r, "$X").last().unwrap(), "ok");
    }
    w.write_all(b"?").unwrap();
    let report = read_until(&mut r, |s| s.starts_with('<'));
    assert!(report.last().unwrap().starts_with("<Idle|"), "{report:?}");
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    // The capture: the pulses and the end of exactly the lines answered `ok`.
    let s = &served.summary;
    let pulses: (i64, i64) = ran.iter().fold((0, 0), |a, m| (a.0 + m.0, a.1 + m.1.abs()));
    assert_eq!(
        (
            s["pulses"]["x"].as_i64(),
            s["pulses"]["y"].as_i64(),
            s["pulses"]["z"].as_i64()
        ),
        (Some(pulses.0), Some(pulses.1), Some(0)),
        "{s}"
    );
    let [x, y, z] = millac_qemu::analysis::vcd::positions(0, &served.capture.pins);
    assert_eq!((x, y, z), (end.0, end.1, 0));
    let p = &s["final_position_blu"];
    assert_eq!(
        (p["x"].as_i64(), p["y"].as_i64(), p["z"].as_i64()),
        (Some(end.0), Some(end.1), Some(0))
    );
    // The session analysed like a run of its log: one block per line that ran, each ending on its
    // end point, pulse for pulse the host core's.
    assert_eq!(s["blocks"].as_u64(), Some(ran.len() as u64), "{s}");
    assert_eq!(s["end_points_exact"], true, "{s}");
    assert_eq!(s["pulses_match_host"], true, "{s}");
    // ... and `run` of that log: the same keys, blocks, pulses and position.
    let log = std::fs::read_to_string(out.join("serve.nc")).unwrap();
    let run = millac_qemu::emulator::runner::run(&log, &out.join("run"), 4).expect("run serve.nc");
    let keys = |v: &serde_json::Value| {
        let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        k.retain(|k| k != "virtual_time_s");
        k.sort();
        k
    };
    assert_eq!(keys(s), keys(&run.summary));
    for k in ["blocks", "pulses", "final_position_blu", "end_points_exact"] {
        assert_eq!(s[k], run.summary[k], "{k}");
    }
}

/// X of a status report's `MPos:` in mm.
fn mpos_x(report: &str) -> f64 {
    report
        .split('|')
        .find_map(|f| f.strip_prefix("MPos:"))
        .and_then(|p| p.split(',').next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no MPos in {report}"))
}

/// A jog right behind a line runs after the line's block (review of issue 7: it was queued ahead
/// of the look-ahead's held block, so the moves ran out of order and the jog's soft-limit check
/// assumed the wrong start); 0x85 cancels a running jog, which stops short at the acceleration and
/// the parser stands there; a soft reset while a line runs stops it at once with `ALARM:3`, the
/// queue flushed and the position exact (the capture's end equals the last report).
#[test]
fn jogs_keep_their_order_and_jog_cancel_and_reset_stop_motion() {
    let Session {
        addr, stop, server, ..
    } = start("stop");
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    // In one write: a line (held by the look-ahead) and a jog back right behind it.
    w.write_all(b"G90 G21 G1 X2.54 F300\n$J=G90 G21 X0 F300\n")
        .unwrap();
    for _ in 0..2 {
        let got = read_until(&mut r, |s| s == "ok" || s.starts_with("error:"));
        assert_eq!(got.last().unwrap(), "ok", "{got:?}");
    }
    assert!(poll_idle(&mut w, &mut r).starts_with("<Idle|MPos:0.000,"));
    // Jog cancel.
    assert_eq!(
        ask(&mut w, &mut r, "$J=G91 G21 X25.4 F600").last().unwrap(),
        "ok"
    );
    let mut seen = Vec::new();
    poll_until(&mut w, &mut r, &mut seen, |s| s.starts_with("<Jog"));
    std::thread::sleep(Duration::from_millis(300));
    w.write_all(&[0x85]).unwrap();
    let idle = poll_idle(&mut w, &mut r);
    let x = mpos_x(&idle);
    assert!(x > 0.0 && x < 25.4, "jog cancel stopped at {x} mm");
    // The parser stands where the jog stopped, its modes kept (G90 G21 from the first line): a
    // move to X0 from there ends at 0.
    assert_eq!(ask(&mut w, &mut r, "G0 X0").last().unwrap(), "ok");
    assert!(poll_idle(&mut w, &mut r).starts_with("<Idle|MPos:0.000,"));
    // Reset during motion.
    assert_eq!(
        ask(&mut w, &mut r, "G91 G21 G1 X25.4 F600").last().unwrap(),
        "ok"
    );
    assert_eq!(ask(&mut w, &mut r, "G1 X25.4").last().unwrap(), "ok");
    poll_until(&mut w, &mut r, &mut seen, |s| s.starts_with("<Run"));
    std::thread::sleep(Duration::from_millis(300));
    w.write_all(&[0x18]).unwrap();
    let after = read_until(&mut r, |s| s.starts_with("ALARM:"));
    assert_eq!(after.last().unwrap(), "ALARM:3", "{after:?}");
    let alarm = poll_until(&mut w, &mut r, &mut seen, |_| true)
        .pop()
        .unwrap();
    assert!(alarm.starts_with("<Alarm|"), "{alarm}");
    let x = mpos_x(&alarm);
    assert!(x > 0.0 && x < 25.4, "reset stopped at {x} mm");
    std::thread::sleep(Duration::from_millis(300));
    let still = poll_until(&mut w, &mut r, &mut seen, |_| true)
        .pop()
        .unwrap();
    assert_eq!(mpos_x(&still), x, "moved after the reset: {still}");
    assert_eq!(ask(&mut w, &mut r, "$X").last().unwrap(), "ok");
    let idle = poll_idle(&mut w, &mut r);
    assert_eq!(mpos_x(&idle), x);
    // A sender that disconnects and reconnects finds the machine as it left it (no reset sent).
    drop((w, r));
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    let mpos = |s: &str| s.split('|').nth(1).unwrap_or("").to_string();
    assert_eq!(mpos(&poll_idle(&mut w, &mut r)), mpos(&idle));
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    // The first pulses are the line's (+X), not the jog's; the capture ends at the reported stop.
    let edges = millac_qemu::analysis::edges(0, &served.capture.pins).edges;
    assert_eq!((edges[0].axis, edges[0].dir), (0, 1), "{:?}", edges[0]);
    let end_x = served.summary["final_position_blu"]["x"].as_i64().unwrap();
    assert!(
        (end_x as f64 * 0.00254 - x).abs() < 0.0006,
        "capture ends at {end_x} BLU, reported {x} mm"
    );
}

/// The QEMU processes a process (thread) started, from /proc.
fn qemu_children(pid: u32) -> Vec<u32> {
    let mut found = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return found;
    };
    for t in tasks.flatten() {
        let children = std::fs::read_to_string(t.path().join("children")).unwrap_or_default();
        for c in children
            .split_whitespace()
            .filter_map(|c| c.parse::<u32>().ok())
        {
            let comm = std::fs::read_to_string(format!("/proc/{c}/comm")).unwrap_or_default();
            if comm.trim() == "qemu-system-arm" {
                found.push(c);
            }
        }
    }
    found
}

/// QEMU never outlives the host tool: a `serve` killed outright (SIGKILL, or a test that panics
/// and ends its process) takes its QEMU with it (the child asks the kernel for SIGKILL when its
/// parent dies). Before, the QEMU went on running, holding its port, until killed by hand.
#[test]
fn qemu_dies_with_the_tool_that_started_it() {
    let out = fresh("orphan");
    let addr = format!("127.0.0.1:{}", free_port());
    let mut tool = std::process::Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(["serve", "--nc-only", "--tcp", &addr, "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("millac-qemu serve");
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    let qemu = qemu_children(tool.id());
    assert_eq!(qemu.len(), 1, "{qemu:?}");
    tool.kill().unwrap();
    tool.wait().unwrap();
    let t0 = Instant::now();
    while std::path::Path::new(&format!("/proc/{}", qemu[0])).exists() {
        // A zombie is dead too (reaped by init).
        let state = std::fs::read_to_string(format!("/proc/{}/stat", qemu[0])).unwrap_or_default();
        if state.split_whitespace().nth(2) == Some("Z") {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "QEMU {} outlived its parent",
            qemu[0]
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The measured force (`f_n` of ac.log, N) of every AC period of a serve session that streams
/// a 1 in full slot 0.3 in deep at F10 after `spindle` (e.g. `S1200 M3`), the ADC measuring only;
/// and the peak force over the limit of the host's run of the session's program at its
/// programmed feeds (summary.json `ac.programmed_peak_force_ratio`).
fn slot_forces(tag: &str, spindle: &str) -> (Vec<f64>, f64) {
    let out = fresh(tag);
    let (stop, server, mut w, mut r) = serve_steel_block(&out, 3, false);
    let program = format!("G20 G90\n{spindle}\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.5 F10\nG0 Z0.1\n");
    let mut seen = Vec::new();
    for line in program.lines() {
        assert_eq!(send_line(&mut w, &mut r, line, &mut seen), "ok", "{line}");
    }
    poll_idle(&mut w, &mut r);
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let log = std::fs::read_to_string(out.join("ac.log")).unwrap();
    let forces = log
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(6)?.parse().ok())
        .collect();
    let host = served.summary["ac"]["programmed_peak_force_ratio"]
        .as_f64()
        .unwrap();
    (forces, host)
}

/// Issue 9: the S word a sender streams sets the simulated spindle speed in `serve` (the
/// firmware's spindle change reaches the plant through the ADC's requests, after the motion
/// before it): at the same feed, S1200 cuts half the chip per tooth of S600, so about half the
/// force. Before, the plant turned at 600 rpm whatever S the session sent.
#[test]
fn the_s_word_of_a_session_sets_the_simulated_spindle_speed() {
    let peak = |f: &[f64]| f.iter().copied().fold(0.0, f64::max);
    let (f600, host600) = slot_forces("s600", "S600 M3");
    let (f1200, host1200) = slot_forces("s1200", "S1200 M3");
    let (p600, p1200) = (peak(&f600), peak(&f1200));
    eprintln!(
        "peak measured force: S600 {p600:.0} N, S1200 {p1200:.0} N; host runs {host600:.3}, \
         {host1200:.3} of the limit"
    );
    assert!(p600 > 1000.0, "S600: {p600} N (no cut?)");
    let ratio = p1200 / p600;
    assert!((ratio - 0.5).abs() < 0.05, "S1200 / S600 = {ratio}");
    // The report's host runs cut at the session's speed too (the default tool: 4000 N).
    for (p, host) in [(p600, host600), (p1200, host1200)] {
        assert!((host * 4000.0 / p - 1.0).abs() < 0.1, "{host} vs {p} N");
    }
}

/// A client of the session: its two ends, past the banner the port greets it with (nothing
/// sent: bCNC and CNCjs do not reset on open).
fn greeted(addr: &str) -> (TcpStream, BufReader<TcpStream>) {
    let stream = connect(addr);
    let w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    let hello = whole_banner(&mut r, Duration::from_secs(120));
    assert!(hello.is_some(), "no banner on connect");
    r.get_ref()
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    (w, r)
}

/// The end of `program` from the origin in the default modes, BLU.
fn end_of(program: &str) -> [i64; 3] {
    let p = millac_qemu::analysis::load_program(program, &millac::Settings::default()).unwrap();
    p.last().unwrap().end.map(i64::from)
}

/// The G-code lines the firmware accepted in a session (its log `serve.nc` without markers).
fn gcode_lines(out: &std::path::Path) -> Vec<String> {
    let log = std::fs::read_to_string(out.join("serve.nc")).unwrap();
    log.lines()
        .filter(|l| !millac::wire::SessionLine::is_marker(l))
        .map(str::to_string)
        .collect()
}

/// The capture's end position in a session's summary.
fn final_blu(s: &serde_json::Value) -> [i64; 3] {
    let p = &s["final_position_blu"];
    ["x", "y", "z"].map(|k| p[k].as_i64().unwrap())
}

/// One cable: a client leaves `G0 X1` unfinished (no line end) and disconnects; the next client
/// is greeted with the banner without sending anything, its `G0 Y1` is answered `ok` and the
/// machine goes to Y1 only. Before, the next client saw no banner and its first line was glued
/// to the half line (`G0 X1G0 Y1`: an error, or a move made of two halves).
#[test]
fn a_half_line_left_by_a_client_is_dropped_and_the_next_client_starts_clean() {
    let Session {
        out,
        addr,
        stop,
        server,
    } = start("half-line");
    {
        let (mut w, _r) = greeted(&addr);
        w.write_all(b"G0 X1").unwrap();
    }
    let (mut w, mut r) = greeted(&addr);
    assert_eq!(ask(&mut w, &mut r, "G0 Y1").last().unwrap(), "ok");
    let idle = poll_idle(&mut w, &mut r);
    assert!(idle.starts_with("<Idle|MPos:0.000,25.400,0.000|"), "{idle}");
    drop((w, r));
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let s = &served.summary;
    assert_eq!(final_blu(s), end_of("G0 Y1\n"), "{s}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(gcode_lines(&out), ["G0 Y1"]);
}

/// One cable: a client ends its last line with a lone CR (as a sender set to CR line ends does)
/// and disconnects; the next client's empty line (a sender's wake-up) is answered `ok`. Before,
/// the firmware took that LF as the second half of the CR's CRLF and never answered it.
#[test]
fn a_lone_cr_left_by_a_client_does_not_swallow_the_next_clients_line_end() {
    let Session {
        out: _,
        addr,
        stop,
        server,
    } = start("lone-cr");
    {
        let (mut w, mut r) = greeted(&addr);
        w.write_all(b"G0 X1\r").unwrap();
        let got = read_until(&mut r, |s| s == "ok" || s.starts_with("error:"));
        assert_eq!(got.last().unwrap(), "ok");
    }
    let (mut w, mut r) = greeted(&addr);
    r.get_ref()
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    assert_eq!(ask(&mut w, &mut r, "").last().unwrap(), "ok");
    assert_eq!(ask(&mut w, &mut r, "G0 Y1").last().unwrap(), "ok");
    let idle = poll_idle(&mut w, &mut r);
    assert!(
        idle.starts_with("<Idle|MPos:25.400,25.400,0.000|"),
        "{idle}"
    );
    drop((w, r));
    stop.store(true, Ordering::SeqCst);
    server.join().unwrap().expect("serve");
}

/// One cable: while a client is connected, a second one gets one line saying the port is in
/// use and is closed; what it sent never runs, and the first client's stream goes on as before
/// (its replies, in order, nothing of the refusal). Before, the second client's bytes waited
/// unseen and ran when the first left.
#[test]
fn a_second_client_is_refused_and_its_bytes_never_run() {
    let Session {
        out,
        addr,
        stop,
        server,
    } = start("second");
    let (mut w, mut r) = greeted(&addr);
    assert_eq!(ask(&mut w, &mut r, "G20 G91").last().unwrap(), "ok");
    let mut other = connect(&addr);
    other.write_all(b"G0 X1\n").unwrap();
    other
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    let mut told = String::new();
    BufReader::new(other)
        .read_to_string(&mut told)
        .expect("the refusal, then the end");
    assert_eq!(
        told,
        format!("{}\r\n", millac_qemu::emulator::port::REFUSED)
    );
    let got = ask(&mut w, &mut r, "G0 Y0.1");
    assert_eq!(got, ["ok"]);
    let idle = poll_idle(&mut w, &mut r);
    assert!(idle.starts_with("<Idle|MPos:0.000,2.540,0.000|"), "{idle}");
    drop((w, r));
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let s = &served.summary;
    assert_eq!(final_blu(s), [0, 1000, 0], "{s}");
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(gcode_lines(&out), ["G20 G91", "G0 Y0.1"]);
}

/// A session that ends in an alarm with accepted lines not run is not `completed`: a soft reset
/// during a feed (`ALARM:3`, the queue dropped) and the stop. The summary's `hold` says the
/// state the machine ended in, the alarm, the line that did not finish and the blocks done.
/// Before, `completed` was true and there was no `hold`.
#[test]
fn a_session_that_ends_in_an_alarm_with_lines_not_run_is_not_completed() {
    let Session {
        addr, stop, server, ..
    } = start("alarm-end");
    let (mut w, mut r) = greeted(&addr);
    for line in ["G20 G91 G1 F10 X1", "G1 Y0.5"] {
        assert_eq!(ask(&mut w, &mut r, line).last().unwrap(), "ok", "{line}");
    }
    let t0 = Instant::now();
    loop {
        w.write_all(b"?").unwrap();
        let report = read_until(&mut r, |s| s.starts_with('<')).pop().unwrap();
        if report.starts_with("<Run") && mpos_x(&report) > 0.0 {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "never ran: {report}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    w.write_all(&[0x18]).unwrap();
    read_until(&mut r, |s| s == "ALARM:3");
    drop((w, r));
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let s = &served.summary;
    assert_eq!(s["completed"], false, "{s}");
    let h = &s["hold"];
    assert_eq!(h["state"], "Alarm", "{s}");
    assert_eq!(h["alarm"], "ALARM:3", "{s}");
    assert_eq!(h["block"], 1, "{s}");
    assert_eq!(h["blocks_done"], 0, "{s}");
    assert_eq!(h["position_blu"], s["final_position_blu"], "{s}");
}

/// The machine model of the tool-change tests: a tool setter whose pad's top is at true Z -20
/// mm (-7 874 BLU) at X, Y 10 mm; tool 1 is 10 mm long (3 937 BLU), tool 2 15 mm (5 906).
const SETTER: millac::inputs::LimitSwitches = millac::inputs::LimitSwitches {
    start: [0; 3],
    at: [500_000; 3],
    negative: 0,
    probe: None,
    setter: Some([3_937, 3_937, -7_874, 400]),
    tools: {
        let mut t = [0; millac::inputs::TOOLS];
        t[0] = 3_937;
        t[1] = 5_906;
        t
    },
};

/// A status report's MPos, mm.
fn mpos_mm(report: &str) -> [f64; 3] {
    let v: Vec<f64> = report
        .split('|')
        .find_map(|f| f.strip_prefix("MPos:"))
        .unwrap_or_else(|| panic!("no MPos in {report}"))
        .split(',')
        .map(|x| x.trim_end_matches('>').parse().unwrap())
        .collect();
    [v[0], v[1], v[2]]
}

/// Where a machine coordinate of `mm` lands (a whole BLU, 0.0001 in), as the report says it.
fn on_blu(mm: f64) -> f64 {
    ((mm / 0.00254).round() * 2.54).round() / 1000.0
}

/// `$#`'s `[TLO:z]`, mm.
fn tlo_mm(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> f64 {
    let got = ask(w, r, "$#");
    got.iter()
        .find_map(|l| l.strip_prefix("[TLO:")?.strip_suffix(']'))
        .unwrap_or_else(|| panic!("no TLO in {got:?}"))
        .parse()
        .unwrap()
}

/// Polls `?` until the machine holds standing (`Hold:0`), then presses cycle start (`~`), as an
/// operator answers a sender's "Continue" prompt. Returns the report that held.
fn continue_at_hold(w: &mut TcpStream, r: &mut BufReader<TcpStream>) -> String {
    let t0 = Instant::now();
    loop {
        w.write_all(b"?").unwrap();
        let s = read_until(r, |s| s.starts_with('<')).pop().unwrap();
        if s.starts_with("<Hold:0|") {
            w.write_all(b"~").unwrap();
            return s;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "never held: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends each line as a line-by-line sender does (the next after the last one's `ok`); every
/// answer must be `ok`. `M0` lines hold: the operator continues once the machine stands.
fn run_lines(w: &mut TcpStream, r: &mut BufReader<TcpStream>, sender: &str, lines: &[&str]) {
    for line in lines {
        let got = ask(w, r, line);
        assert_eq!(got.last().unwrap(), "ok", "{sender}: {line}: {got:?}");
        assert!(
            !got.iter().any(|l| l.starts_with("ALARM")),
            "{sender}: {line}: {got:?}"
        );
        if line.eq_ignore_ascii_case("m0") {
            continue_at_hold(w, r);
        }
    }
}

/// Tool changes under QEMU through `serve`, one session, the machine model's setter:
/// - millac's own (`$341=2`; what CNCjs's "Send M6", bCNC's policy 0 and UGS without its
///   interceptor put on the wire: `T1 M6` as written): the machine goes to the G30 position and
///   holds naming T1; after `~` it measures the tool in the spindle (none, first) and T1 on the
///   setter, returns with T1's tip where the spindle's was, and answers `ok`; the offset is
///   T1's length (10 mm).
/// - bCNC's manual tool change (policy 3, TLO) for T2, its lines as `CNC.toolChange()` writes
///   them (lower case, no spaces, `g53` in `g91`, `m0` holds): probed on the setter, `g43.1z`
///   from its `[PRB:]` less the calibration's, back to where it began.
/// - UGS's tool-change interceptor for T2 (an empty line for the M6, `T2`, up to the program's
///   top, `M5`, the restore lines).
/// - CNCjs's manual TLO tool change (policy 3), its macro's lines for T1.
///
/// Every line is `ok`, nothing alarms, and each sequence ends where the sender meant it to.
#[test]
fn the_senders_tool_changes_run_through_serve() {
    let Session {
        addr,
        stop,
        server,
        out,
    } = start_machine(
        fresh("toolchange"),
        fresh("toolchange-state").join("settings.bin"),
        Some(SETTER),
    );
    let stream = connect(&addr);
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    banner(&mut w, &mut r);
    for set in [
        "$341=2", "$345=10", "$346=10", "$342=60", "$343=100", "$344=600", "$27=0.5",
    ] {
        assert_eq!(ask(&mut w, &mut r, set).last().unwrap(), "ok", "{set}");
    }
    run_lines(
        &mut w,
        &mut r,
        "set-up",
        &["G21 G90 G0 X0 Y0 Z25", "G30.1", "G0 X5 Y5 Z-2"],
    );
    // millac's own change: the M6's answer comes after the change.
    w.write_all(b"T1 M6\n").unwrap();
    let told = read_until(&mut r, |s| s.starts_with("[MSG:Tool change"));
    assert_eq!(
        told.last().unwrap(),
        "[MSG:Tool change (M6): fit T1, then cycle start]"
    );
    let held = continue_at_hold(&mut w, &mut r);
    assert_eq!(mpos_mm(&held), [0.0, 0.0, 25.001], "{held}");
    let got = read_until(&mut r, |s| s == "ok" || s.starts_with("error:"));
    assert_eq!(got.last().unwrap(), "ok", "{got:?}");
    let s = poll_idle(&mut w, &mut r);
    // T1's tip where the spindle's was: the spindle 10 mm higher.
    assert_eq!(mpos_mm(&s), [5.001, 5.001, 8.001], "{s}");
    assert_eq!(tlo_mm(&mut w, &mut r), 10.0);

    // bCNC, policy 3 (TLO), T1 still in the spindle (its calibration: the touch of the tool
    // the work was zeroed with, here T1 at machine Z -10.000).
    let toolmz = -10.0;
    run_lines(
        &mut w,
        &mut r,
        "bCNC",
        &[
            "$g",
            "m5",
            "g53g0z25.0",
            "g53g0x0.0y0.0",
            "m0",
            "g53g0x10.0y10.0",
            "g53g0z-8.0",
            "g91G38.2f100.0z-5.0",
        ],
    );
    let prb = ask(&mut w, &mut r, "$#");
    let prbz: f64 = prb
        .iter()
        .find_map(|l| l.strip_prefix("[PRB:"))
        .and_then(|l| l.split(':').next())
        .map(|xyz| xyz.split(',').nth(2).unwrap().parse().unwrap())
        .unwrap();
    assert_eq!(prbz, -10.0, "T1 touches the setter 10 mm up: {prb:?}");
    let tlo = format!("g43.1z{}", prbz - toolmz);
    run_lines(
        &mut w,
        &mut r,
        "bCNC",
        &[
            "g4p1",
            &tlo,
            "g53g0z25.0",
            "g53g0x0.0y0.0",
            "m0",
            "g90",
            "g0x5.0y5.0",
            "g0z-2.0",
            "f1000.0M3",
            "g4p0.5",
        ],
    );
    let s = poll_idle(&mut w, &mut r);
    // Work Z -2 with the offset bCNC set (0: the same tool): machine Z -2.
    assert_eq!(mpos_mm(&s), [5.001, 5.001, on_blu(-2.0)], "{s}");
    assert_eq!(tlo_mm(&mut w, &mut r), 0.0);

    // UGS's interceptor: the M6 line replaced by an empty line, its T word alone, up to the
    // program's top, the spindle off, the operator's pause (nothing sent), up again, restore.
    run_lines(
        &mut w,
        &mut r,
        "UGS",
        &[
            "",
            "T2",
            "G90 G0 Z25.000",
            "M5",
            "G90 G0 Z25.000",
            "G21 G90",
            "M3S12000.0F1000.0",
            "G90 G0X5.000Y5.000",
            "G90 G0Z-2.000",
            "G21G90G91.1G94G54G17",
        ],
    );
    let s = poll_idle(&mut w, &mut r);
    assert_eq!(mpos_mm(&s), [5.001, 5.001, on_blu(-2.0)], "{s}");

    // CNCjs, policy 3 (manual TLO), for T1: its macro's lines (the change position 0, 0, 25;
    // the probe position over the setter at Z -8; a probe distance of 5, feed 100).
    run_lines(
        &mut w,
        &mut r,
        "CNCjs",
        &[
            "T1 (M6)",
            "G4 P0.5",
            "M5",
            "G90",
            "G53 G0 Z25",
            "G53 G0 X0 Y0",
            "G4 P0.5",
            "M0",
            "G53 G0 X10 Y10",
            "G53 G0 Z-8",
            "G4 P0.5",
            "G91 G38.2 F100 Z-5",
            "G4 P1",
        ],
    );
    // `G43.1 Z<posz - touch plate height>`: posz, the work Z from the status report (MPos less
    // the work offset: here the TLO, 0), the plate 0.
    w.write_all(b"?").unwrap();
    let s = read_until(&mut r, |s| s.starts_with('<')).pop().unwrap();
    let posz = mpos_mm(&s)[2];
    assert_eq!(posz, -10.0, "{s}");
    let tlo = format!("G43.1 Z{posz}");
    run_lines(
        &mut w,
        &mut r,
        "CNCjs",
        &[
            &tlo,
            "G53 G0 Z25",
            "G53 G0 X0 Y0",
            "G4 P0.5",
            "M0",
            "G90",
            "G0 X5 Y5",
            "G0 Z-2",
            "M3",
            "G4 P0.5",
        ],
    );
    let s = poll_idle(&mut w, &mut r);
    // Work Z -2 with TLO -10: machine Z -12.
    assert_eq!(mpos_mm(&s), [5.001, 5.001, on_blu(-12.0)], "{s}");
    assert_eq!(tlo_mm(&mut w, &mut r), -10.0);
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    // The session's report: completed (Idle at the end), its probes' cut moves named, and its
    // end where the machine stands (the tool-change moves are in `serve.nc` as moves).
    let s = &served.summary;
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["replay"]["whole"], false, "{s}");
    assert_eq!(s["final_position_blu"]["z"], -4_724, "{s}");
    let log = std::fs::read_to_string(served_log(&out)).unwrap();
    assert!(log.contains("(millac:move G21G53G0Z25."), "{log}");
    assert!(log.contains("(millac:cut "), "{log}");
}

/// The session log `serve` leaves in its folder.
fn served_log(out: &std::path::Path) -> std::path::PathBuf {
    out.join(millac_qemu::lm3s_files::SERVE_LOG_NAME)
}
