//! `serve` under QEMU (host): the firmware in serial mode with UART0 on a TCP port. A client
//! connects, reads the grbl banner, streams G-code lines and gets one answer per line, polls `?`
//! until the machine is idle, and after the stop the capture ends where the lines programmed.
use millac_qemu::serve;
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
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
        let n = r.read_line(&mut l).expect("read from the serial port");
        assert!(n > 0, "serial port closed; so far: {got:?}");
        let l = l.trim_end().to_string();
        let stop = done(&l);
        got.push(l);
        if stop {
            return got;
        }
    }
}

#[test]
fn a_sender_streams_lines_over_tcp_and_the_capture_ends_where_they_programmed() {
    let out = std::env::temp_dir().join(format!("millac-serve-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let addr = format!("127.0.0.1:{}", free_port());
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let (out, addr, stop) = (out.clone(), addr.clone(), stop.clone());
        std::thread::spawn(move || serve::serve(&out, &addr, 4, None, stop))
    };
    let stream = connect(&addr);
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    let mut w = stream.try_clone().unwrap();
    let mut r = BufReader::new(stream);
    // A soft reset asks for the banner (the first one went out before we connected).
    w.write_all(&[0x18]).unwrap();
    let banner = read_until(&mut r, |l| l.starts_with("[MSG:millac"));
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
    assert_eq!(answers, ["ok", "ok", "error:20", "ok", "ok", "ok"]);
    // `?` until idle (the last line ran after the look-ahead found no next line).
    let t0 = Instant::now();
    let last = loop {
        w.write_all(b"?").unwrap();
        let got = read_until(&mut r, |s| s.starts_with('<'));
        let s = got.last().unwrap().clone();
        if s.starts_with("<Idle") {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "never idle: {s}");
        std::thread::sleep(Duration::from_millis(100));
    };
    // 0.029 in = 0.7366 mm, 0.004 in = 0.1016 mm.
    assert_eq!(last, "<Idle|MPos:0.737,0.102,0.000|FS:0,0>");
    stop.store(true, Ordering::SeqCst);
    let served = server.join().unwrap().expect("serve");
    let p = &served.summary["final_position_blu"];
    assert_eq!(
        (p["x"].as_i64(), p["y"].as_i64(), p["z"].as_i64()),
        (Some(290), Some(40), Some(0))
    );
    assert!(out.join("capture.vcd").exists());
    assert!(served.summary["frames"].as_u64().unwrap() > 0);
}
