//! Host tests of the receive side: the 128-byte ring and the character-counting contract, bytes
//! refused by a full ring, soft reset at its place in the stream, realtime bytes anywhere in a
//! line, override arithmetic.

extern crate std;
use super::super::rx::byte;
use super::super::*;
use super::util::{Ev, Rig};
use proptest::prelude::*;
use std::string::String;
use std::vec::Vec;

fn gcode(events: &[Ev]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            Ev::Gcode(l, _) => Some(l.clone()),
            _ => None,
        })
        .collect()
}

/// 128 bytes are accepted with nothing read; the 129th is refused, counted and reported, never
/// silently dropped; realtime bytes still pass while the ring is full.
#[test]
fn exactly_128_bytes_then_refused_and_reported() {
    let mut r = Rig::new();
    let line = b"G0 X0.001\n"; // 10 bytes
    let mut sent = Vec::new();
    while sent.len() + line.len() <= RX_BUFFER_SIZE {
        sent.extend_from_slice(line);
    }
    sent.extend_from_slice(&b"M5\r\nM5 X"[..RX_BUFFER_SIZE - sent.len()]);
    assert_eq!(sent.len(), 128);
    assert!(r.push(&sent).iter().all(|p| *p == Push::Stored));
    assert_eq!(r.p.rx_available(), 0);
    assert_eq!(r.isr.push_byte(b'1'), Push::Refused);
    // The loader reads a line and makes room, but the ring stays poisoned: a later byte is
    // refused too, so the bytes stored are always an unbroken prefix of the stream.
    assert_eq!(r.poll(), Some(Ev::Gcode("G0 X0.001".into(), false)));
    assert!(r.p.rx_available() > 0);
    assert_eq!(r.isr.push_byte(b'\n'), Push::Refused);
    assert_eq!(r.isr.push_byte(b'?'), Push::Realtime(b'?'));
    let ev = r.run();
    assert_eq!(ev[0], Ev::Realtime(Pending(Pending::STATUS)));
    // The 12 complete lines and M5 ran; the partial "M5 X" lost its tail and is refused at its end.
    assert_eq!(gcode(&ev).len(), 12);
    assert_eq!(ev.last(), Some(&Ev::Overflow(2)));
    assert_eq!(r.responses().len(), 13);
    assert_eq!(r.p.rx_available(), RX_BUFFER_SIZE);
    assert_eq!(r.feed(b"0.5\nG0 X0.002\n").len(), 2);
    assert_eq!(r.responses(), ["error:11", "ok"]);
}

/// A sender that keeps the character-counting contract (at most 128 bytes of unanswered lines in
/// flight) is never refused, whatever the loader's timing, and gets one answer per line in order.
#[test]
fn character_counting_sender_is_never_refused() {
    let lines: Vec<String> = (0..300)
        .map(|i| match i % 4 {
            0 => std::format!("G1 X{}.{} F20", i % 7, i),
            1 => String::new(),
            2 => std::format!("G0 Y0.{i} (a comment of some length to fill the ring)"),
            _ => std::format!("G1 X0 Y0 Z-0.0{} F{}", i % 10, 5 + i % 20),
        })
        .collect();
    let mut r = Rig::new();
    let mut in_flight: std::collections::VecDeque<usize> = Default::default();
    let (mut next, mut answers, mut polls) = (0, 0, 0u64);
    while answers < lines.len() {
        // Send as many whole lines as fit.
        while next < lines.len() {
            let n = lines[next].len() + 1;
            if in_flight.iter().sum::<usize>() + n > RX_BUFFER_SIZE {
                break;
            }
            let mut bytes = lines[next].clone().into_bytes();
            bytes.push(b'\n');
            assert!(r.push(&bytes).iter().all(|p| *p == Push::Stored));
            in_flight.push_back(n);
            next += 1;
        }
        // The loader reads a little (one poll every other round).
        polls += 1;
        if polls % 2 == 0 {
            r.poll();
        }
        for resp in r.responses() {
            assert_eq!(resp, "ok", "line {answers}: {}", lines[answers]);
            in_flight.pop_front().expect("an answer per line sent");
            answers += 1;
        }
    }
    assert!(in_flight.is_empty());
}

/// A soft reset discards the lines before it (unanswered, as grbl), sends the banner, and the
/// bytes after it belong to the new session, even when they were already in the ring.
#[test]
fn reset_cuts_the_stream_at_its_place() {
    let mut r = Rig::new();
    r.push(b"G21\nG0 X1\nG0 Y");
    r.push(&[byte::RESET]);
    r.push(b"G0 Z-0.1\n");
    let ev = r.run();
    assert_eq!(ev[0], Ev::Reset);
    assert_eq!(gcode(&ev), ["G0 Z-0.1"]);
    let out = r.take();
    assert!(
        out.starts_with("\r\nGrbl 1.1h ['$' for help]\r\n[MSG:millac "),
        "{out}"
    );
    assert!(
        out.ends_with("ok\r\n") && out.matches("ok").count() == 1,
        "{out}"
    );
    // A reset arriving while a line is half read: the half line is gone.
    r.push(b"G0 X");
    r.poll();
    r.push(&[byte::RESET]);
    r.push(b"1\nM5\n");
    let ev = r.run();
    assert_eq!(ev[0], Ev::Reset);
    assert_eq!(gcode(&ev), ["1", "M5"]);
    // Two resets: two banners, nothing before the second survives.
    r.take();
    r.push(b"G0 X1\n\x18G0 Y1\n\x18M5\n");
    let ev = r.run();
    assert_eq!(ev.iter().filter(|e| **e == Ev::Reset).count(), 2);
    assert_eq!(gcode(&ev), ["M5"]);
    assert_eq!(r.take().matches("Grbl 1.1h").count(), 2);
}

/// A reset into a full ring flushes everything received so far, and the ring works again. A byte
/// refused after the reset belonged to the new session: it is reported after the reset and its
/// line is refused.
#[test]
fn reset_into_a_full_ring_flushes_it() {
    let mut r = Rig::new();
    r.push(&[b'X'; RX_BUFFER_SIZE]);
    assert_eq!(r.isr.push_byte(byte::RESET), Push::Realtime(byte::RESET));
    assert_eq!(r.run(), [Ev::Reset]);
    assert_eq!(r.p.rx_available(), RX_BUFFER_SIZE);
    assert_eq!(gcode(&r.feed(b"M5\n")), ["M5"]);
    r.push(&[b'X'; RX_BUFFER_SIZE]);
    assert_eq!(r.isr.push_byte(byte::RESET), Push::Realtime(byte::RESET));
    assert_eq!(r.isr.push_byte(b'Y'), Push::Refused);
    assert_eq!(r.run(), [Ev::Reset, Ev::Overflow(1)]);
    assert_eq!(r.p.rx_available(), RX_BUFFER_SIZE);
    r.take();
    assert_eq!(gcode(&r.feed(b"M5\nM5\n")), ["M5"]);
    assert_eq!(r.responses(), ["error:11", "ok"]);
}

/// A sender floods the ring, then sends a soft reset and a line at once (recovering from its own
/// overflow): the ring is still poisoned, so the line's first bytes are refused. They are
/// reported (the alarm's count is theirs alone, not the flood's) and the line is refused whole,
/// never run without its start: "G91 G0 X10" must not run as "G0 X10" (absolute), nor "$X" be
/// dropped without an answer.
#[test]
fn bytes_refused_after_a_reset_are_reported_and_their_line_refused() {
    let mut r = Rig::new();
    r.push(&[b'X'; RX_BUFFER_SIZE]);
    // The flood goes on: refused, counted.
    assert!(r
        .push(b"G0 Y1\nG0 Y2\n")
        .iter()
        .all(|p| *p == Push::Refused));
    assert_eq!(r.isr.push_byte(byte::RESET), Push::Realtime(byte::RESET));
    assert!(r.push(b"G91 ").iter().all(|p| *p == Push::Refused));
    assert_eq!(r.run(), [Ev::Reset, Ev::Overflow(4)]);
    r.take();
    // The loader raises the alarm (what the firmware does with the event).
    r.p.rx_overflow(4, &mut r.out);
    assert_eq!(r.p.alarm_code(), Some(110));
    assert_eq!(
        r.take(),
        "ALARM:110\r\n[MSG:receive overflow: 4 bytes lost]\r\n"
    );
    let ev = r.feed(b"G0 X10\n$X\n");
    assert!(gcode(&ev).is_empty(), "{ev:?}");
    assert_eq!(r.responses(), ["error:11", "ok"]);
    // Only "$X" refused, alone after the reset: reported, and the sender gets an answer.
    r.push(&[b'X'; RX_BUFFER_SIZE]);
    r.push(&[byte::RESET]);
    assert!(r.push(b"$X\n").iter().all(|p| *p == Push::Refused));
    assert_eq!(r.run(), [Ev::Reset, Ev::Overflow(3)]);
    r.take();
    r.feed(b"\n");
    assert_eq!(r.responses(), ["error:11"]);
    // A second reset before the loader came discards the bytes lost after the first one with
    // its lines: two resets, two banners (the first one's marker has a slot of its own beside
    // the full data), and no overflow.
    r.push(&[b'X'; RX_BUFFER_SIZE]);
    r.push(&[byte::RESET]);
    assert!(r.push(b"G0 X1\n").iter().all(|p| *p == Push::Refused));
    r.push(&[byte::RESET]);
    assert_eq!(r.run(), [Ev::Reset, Ev::Reset]);
    assert_eq!(gcode(&r.feed(b"M5\n")), ["M5"]);
}

fn ov_model(mut o: Overrides, b: u8) -> Overrides {
    let clamp = |v: i32| v.clamp(10, 200) as u8;
    match b {
        0x90 => o.feed = 100,
        0x91 => o.feed = clamp(o.feed as i32 + 10),
        0x92 => o.feed = clamp(o.feed as i32 - 10),
        0x93 => o.feed = clamp(o.feed as i32 + 1),
        0x94 => o.feed = clamp(o.feed as i32 - 1),
        0x95 => o.rapid = 100,
        0x96 => o.rapid = 50,
        0x97 => o.rapid = 25,
        0x99 => o.spindle = 100,
        0x9A => o.spindle = clamp(o.spindle as i32 + 10),
        0x9B => o.spindle = clamp(o.spindle as i32 - 10),
        0x9C => o.spindle = clamp(o.spindle as i32 + 1),
        0x9D => o.spindle = clamp(o.spindle as i32 - 1),
        byte::RESET => o = Overrides::NONE,
        _ => {}
    }
    o
}

#[test]
fn overrides_step_and_clamp() {
    let mut r = Rig::new();
    r.push(&[0x91; 15]);
    assert_eq!(r.p.overrides().feed, 200);
    r.push(&[0x92; 25]);
    assert_eq!(r.p.overrides().feed, 10);
    r.push(&[0x93, 0x93, 0x94]);
    assert_eq!(r.p.overrides().feed, 11);
    r.push(&[0x96]);
    assert_eq!(r.p.overrides().rapid, 50);
    r.push(&[0x97]);
    assert_eq!(r.p.overrides().rapid, 25);
    r.push(&[0x9B, 0x9D]);
    assert_eq!(r.p.overrides().spindle, 89);
    assert_eq!(r.run()[0], Ev::Realtime(Pending(Pending::OVERRIDES)));
    // No change, no flag.
    r.push(&[0x97]);
    assert_eq!(r.run(), []);
    r.push(&[0x92]);
    assert_eq!(r.p.overrides().feed, 10);
    assert_eq!(r.run(), [Ev::Realtime(Pending(Pending::OVERRIDES))]);
    r.push(&[0x92, 0x94]);
    assert_eq!(r.run(), []);
    r.push(&[0x90]);
    assert_eq!(r.p.overrides().feed, 100);
    // A soft reset restores 100 %.
    r.push(&[byte::RESET]);
    assert_eq!(r.p.overrides(), Overrides::NONE);
}

/// Every realtime byte at every position of a line (and between the bytes of a CRLF): taken out,
/// the line arrives intact, the request is raised.
#[test]
fn every_realtime_byte_at_every_position() {
    let line = b"G1 X0.5 Y-0.25 F12 (comment)\r\n";
    let rts: Vec<u8> = (0..=255u8).filter(|&b| byte::is_realtime(b)).collect();
    assert_eq!(rts.len(), 22);
    for &rt in &rts {
        for pos in 0..=line.len() {
            let mut r = Rig::new();
            let mut bytes = line.to_vec();
            bytes.insert(pos, rt);
            let pushes = r.push(&bytes);
            assert_eq!(
                pushes.iter().filter(|p| **p == Push::Realtime(rt)).count(),
                1
            );
            let ev = r.run();
            if rt == byte::RESET {
                // The part before the reset is discarded; after it, the rest of the line is one
                // line of its own (or nothing, if the reset came after the CR).
                assert_eq!(ev[0], Ev::Reset, "{pos}");
                continue;
            }
            assert_eq!(
                gcode(&ev),
                ["G1 X0.5 Y-0.25 F12 (comment)"],
                "{rt:#x} at {pos}"
            );
            assert_eq!(r.responses(), ["ok"], "{rt:#x} at {pos}");
        }
    }
}

proptest! {
    /// Random lines with random realtime bytes strewn anywhere: the lines arrive exactly as sent
    /// without them, one answer each, the flags are the union of the requests, and the
    /// overrides follow the model.
    #[test]
    fn realtime_bytes_anywhere(
        lines in prop::collection::vec("[A-Za-z0-9 .()-]{0,40}", 1..6),
        inserts in prop::collection::vec((any::<prop::sample::Index>(), prop::sample::select(
            (0..=255u8).filter(|&b| byte::is_realtime(b) && b != byte::RESET).collect::<Vec<_>>()
        )), 0..20),
    ) {
        let mut clean = Vec::new();
        for l in &lines {
            clean.extend_from_slice(l.as_bytes());
            clean.push(b'\n');
        }
        let mut bytes = clean.clone();
        for (at, rt) in &inserts {
            bytes.insert(at.index(bytes.len() + 1), *rt);
        }
        // The model, in the order the bytes arrive.
        let mut want_flags = 0u8;
        let mut ov = Overrides::NONE;
        for &b in bytes.iter().filter(|b| byte::is_realtime(**b)) {
            want_flags |= match b {
                b'?' => Pending::STATUS,
                b'!' => Pending::HOLD,
                b'~' => Pending::RESUME,
                0x85 => Pending::JOG_CANCEL,
                0x84 => Pending::DOOR,
                _ => 0,
            };
            let next = ov_model(ov, b);
            if next != ov {
                want_flags |= Pending::OVERRIDES;
            }
            ov = next;
        }
        let mut r = Rig::new();
        let ev = r.feed(&bytes);
        let got_flags = ev.iter().fold(0u8, |f, e| match e {
            Ev::Realtime(p) => f | p.0,
            _ => f,
        });
        prop_assert_eq!(got_flags, want_flags);
        prop_assert_eq!(r.p.overrides(), ov);
        let handed: Vec<String> = ev.iter().filter_map(|e| match e {
            Ev::Gcode(l, _) => Some(l.clone()),
            _ => None,
        }).collect();
        let nonempty: Vec<String> = lines.iter().filter(|l| !l.trim().is_empty()).cloned().collect();
        prop_assert_eq!(handed, nonempty);
        prop_assert_eq!(r.responses().len(), lines.len());
    }
}

/// `poll_realtime` (the loader's poll while its block queue is full) serves realtime requests and
/// a reset at once and leaves every received line in the ring, in order, for the next `poll`.
#[test]
fn poll_realtime_serves_requests_and_leaves_the_lines() {
    let mut r = Rig::new();
    r.push(b"G1 X1 F10\nG1 ?X2\n!");
    let ev = r.p.poll_realtime(&mut r.out);
    let Event::Realtime(p) = ev else {
        panic!("{ev:?}")
    };
    assert!(p.status() && p.hold());
    assert!(matches!(r.p.poll_realtime(&mut r.out), Event::None));
    assert_eq!(
        r.p.rx_available(),
        RX_BUFFER_SIZE - "G1 X1 F10\nG1 X2\n".len()
    );
    r.push(b"~");
    assert!(matches!(r.p.poll_realtime(&mut r.out), Event::Realtime(p) if p.resume()));
    let lines = gcode(&r.run());
    assert_eq!(lines, ["G1 X1 F10", "G1 X2"]);
    // A reset is served too; the lines before it are dropped.
    r.push(b"G1 X3\n\x18G1 X4\n");
    assert!(matches!(r.p.poll_realtime(&mut r.out), Event::Reset));
    assert_eq!(gcode(&r.run()), ["G1 X4"]);
}

/// A sender that sends 0x18 twice (a retry, as the serve tests' and many senders' connect does)
/// starts counting 128 bytes at the first banner, while the second reset's marker still sits in
/// the ring: markers must not take the data's room, so all 128 bytes are stored. (The marker took
/// a slot of the 128: the 128th byte was refused and raised a receive overflow; the flood test
/// saw that after a second banner.)
#[test]
fn reset_markers_do_not_take_the_128_bytes() {
    let mut r = Rig::new();
    r.push(&[byte::RESET, byte::RESET]);
    // The loader handles the first reset (banner); the second one's marker is still queued.
    assert_eq!(r.poll(), Some(Ev::Reset));
    assert_eq!(r.p.rx_available(), RX_BUFFER_SIZE);
    let data: Vec<u8> = b"G0 X0.001\n"
        .iter()
        .copied()
        .cycle()
        .take(RX_BUFFER_SIZE)
        .collect();
    let pushed = r.push(&data);
    assert!(pushed.iter().all(|p| *p == Push::Stored), "{pushed:?}");
    assert_eq!(r.p.rx_available(), 0);
    assert_eq!(r.isr.push_byte(b'1'), Push::Refused);
    // The second reset discards nothing after it: every whole line of the 128 bytes comes.
    let ev = r.run();
    assert_eq!(ev[0], Ev::Reset);
    assert_eq!(gcode(&ev).len(), RX_BUFFER_SIZE / 10);
}

/// Bytes the UART lost (a receiver overrun) are reported like bytes the ring refused: the line
/// they belonged to is refused (error:11), the loss raises the overflow event with their count,
/// and later bytes are refused until the loader has reported it.
#[test]
fn a_receiver_overrun_is_reported_like_a_ring_overflow() {
    let mut r = Rig::new();
    assert!(r.push(b"G0 X").iter().all(|p| *p == Push::Stored));
    r.isr.lost_bytes(3);
    assert_eq!(r.isr.push_byte(b'1'), Push::Refused);
    let ev = r.run();
    assert_eq!(ev.last(), Some(&Ev::Overflow(4)), "{ev:?}");
    assert_eq!(r.feed(b"\nG0 X0.002\n").len(), 2);
    assert_eq!(r.responses(), ["error:11", "ok"]);
}

/// The realtime bytes as bCNC and CNCjs write them: UTF-8 encoded (`C2 91`, `C2 90`, `C2 85`,
/// ...), between lines and inside one. The lead byte is dropped, the override applied, and
/// every line arrives intact and is answered `ok` (keeping the `C2` gave the next line
/// `error:1`, and both senders stop a job on an error).
#[test]
fn utf8_encoded_realtime_bytes_of_real_senders() {
    let mut r = Rig::new();
    let mut stream = Vec::new();
    stream.extend_from_slice(b"G21 G90\n");
    stream.extend_from_slice(&[0xC2, byte::FEED_PLUS_10]);
    stream.extend_from_slice(b"G1 X1 F100\n");
    stream.extend_from_slice(&[0xC2, byte::FEED_PLUS_10, 0xC2, byte::FEED_MINUS_1]);
    stream.extend_from_slice(b"G1 X");
    stream.extend_from_slice(&[0xC2, byte::RAPID_50]);
    stream.extend_from_slice(b"2\n");
    stream.extend_from_slice(&[0xC2, byte::FEED_100, 0xC2, byte::JOG_CANCEL]);
    stream.extend_from_slice(&[0xC2, byte::SPINDLE_PLUS_10]);
    stream.extend_from_slice(b"G1 X3\n");
    let pushes = r.push(&stream);
    assert_eq!(pushes.iter().filter(|p| **p == Push::Dropped).count(), 7);
    assert!(!pushes.contains(&Push::Refused));
    assert_eq!(
        r.p.overrides(),
        Overrides {
            feed: 100,
            rapid: 50,
            spindle: 110
        }
    );
    let ev = r.run();
    assert_eq!(gcode(&ev), ["G21 G90", "G1 X1 F100", "G1 X2", "G1 X3"]);
    assert_eq!(r.responses(), ["ok", "ok", "ok", "ok"]);
}

/// The feed override steps of `C2 91` sent one after another reach 120 % (the lead bytes are
/// not counted as anything).
#[test]
fn utf8_encoded_feed_override_steps() {
    let mut r = Rig::new();
    r.push(&[0xC2, 0x91, 0xC2, 0x91, 0xC2, 0x93, 0xC2, 0x94]);
    assert_eq!(r.p.overrides().feed, 120);
    assert_eq!(gcode(&r.feed(b"G0 X0.1\n")), ["G0 X0.1"]);
    assert_eq!(r.responses(), ["ok"]);
}

/// Extended bytes that are no realtime command: between lines dropped (a realtime command of
/// another firmware, such as grblHAL's 0x87, or its UTF-8 form `C2 87`); inside a line kept, so
/// a comment in UTF-8 is accepted and a byte that is not UTF-8 refuses its line (`error:1`)
/// instead of joining the digits around it into another number.
#[test]
fn extended_bytes_between_lines_dropped_inside_a_line_kept() {
    let mut r = Rig::new();
    let mut stream = Vec::new();
    stream.extend_from_slice(&[0x87, 0xC2, 0x87, 0xFF]);
    stream.extend_from_slice(b"G0 X0.1\n");
    stream.extend_from_slice("G0 X0.2 (\u{d8}6 mm cutter, caf\u{e9})\n".as_bytes());
    stream.extend_from_slice(b"G0 X1");
    stream.push(0xFF);
    stream.extend_from_slice(b"0\n");
    stream.extend_from_slice(b"G0 X0.3");
    stream.extend_from_slice(&[0xC2, 0x87]);
    stream.extend_from_slice(b"\n");
    stream.extend_from_slice(b"G0 X0.4\n");
    let pushes = r.push(&stream);
    assert_eq!(pushes[..4], [Push::Dropped; 4]);
    let ev = r.run();
    // The non-UTF-8 line is refused before it becomes a G-code line.
    assert_eq!(
        gcode(&ev),
        [
            "G0 X0.1",
            "G0 X0.2 (\u{d8}6 mm cutter, caf\u{e9})",
            "G0 X0.3\u{87}",
            "G0 X0.4"
        ]
    );
    assert_eq!(
        r.responses(),
        ["ok", "ok", "error:1", "error:1", "ok"],
        "{ev:?}"
    );
}
