//! QEMU co-simulation tests of the adaptive control (host): the firmware samples a toy plant
//! through the lockstep simulated ADC, runs its AC task and writes `ac.log`. A toy plant is
//! enough here: the force is proportional to the feed (the distance moved over the last 10
//! samples); the real cutting model lives in the `millac-plant` crate (qemu/plant).
use millac::ac::AcSettings;
use millac::Settings;
use millac_qemu::analysis;
use millac_qemu::emulator::cosim::{self, AcRecord, Exchange, Plant};
use millac_qemu::emulator::runner;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::Instant;

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("millac-cosim-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Samples per force window of the toy plant (10 ms at 1 kHz).
const WINDOW: usize = 10;
/// Mid-scale code (zero load) of the default calibration.
const MID: f64 = 2048.0;

/// Force (N) = `n_per_blu_s` x path speed (BLU/s) over the last `WINDOW` samples, on Fu; Fv at
/// zero load; T the torque of that force on the default 0.5 in cutter (F*R/T = 0.9, inside the
/// AC's force/torque band). Every channel carries a small deterministic dither (+-2 codes), as a
/// live transducer does (a perfectly still channel while the axes feed is a frozen sensor to the
/// AC). From sample `stuck_from` on, T is stuck at the upper rail.
struct Toy {
    n_per_blu_s: f64,
    hist: VecDeque<[i64; 3]>,
    stuck_from: Option<u32>,
    /// From this sample on the plant's thread dies (a panic): the bridge closes its ends, the
    /// firmware's simulated ADC is gone.
    gone_from: Option<u32>,
}

impl Toy {
    /// A plant whose force reaches F0 at `feed_ipm` (BLU 0.0001 in).
    fn new(feed_ipm: f64, stuck_from: Option<u32>) -> Toy {
        let f0 = f64::from(AcSettings::default().f0_n());
        let blu_s = feed_ipm * 10_000.0 / 60.0;
        Toy {
            n_per_blu_s: f0 / blu_s,
            hist: VecDeque::new(),
            stuck_from,
            gone_from: None,
        }
    }
}

impl Plant for Toy {
    fn sample(&mut self, index: u32, _t_s: f64, pos: [i64; 3]) -> Option<[u16; 3]> {
        if self.gone_from.is_some_and(|g| index >= g) {
            panic!("test: the simulated ADC goes away at sample {index}");
        }
        self.hist.push_back(pos);
        if self.hist.len() > WINDOW + 1 {
            self.hist.pop_front();
        }
        let first = self.hist[0];
        let d2: f64 = (0..3).map(|k| ((pos[k] - first[k]) as f64).powi(2)).sum();
        let n = (self.hist.len() - 1).max(1) as f64;
        let force = self.n_per_blu_s * d2.sqrt() / n * 1000.0;
        let cal = AcSettings::default().cal;
        let dither = [0.0, 2.0, 0.0, -2.0][index as usize % 4];
        let code = |v: f64, k: usize| {
            (MID + v / f64::from(cal[k].gain) + dither)
                .round()
                .clamp(0.0, 4095.0) as u16
        };
        let t = match self.stuck_from {
            Some(s) if index >= s => 4095,
            _ => code(force * 0.00635 / 0.9, 0),
        };
        Some([t, code(force, 1), code(0.0, 2)])
    }
}

const PROGRAM: &str = "G20 G91\nG1 X0.7 F30\nM2\n";
const END_X: i64 = 7000;

struct Run {
    cap: millac_qemu::emulator::capture::Capture,
    exchanges: Vec<Exchange>,
    log: String,
    records: Vec<AcRecord>,
}

fn run(name: &str, program: &str, plant: Toy, enabled: bool) -> Run {
    let out = out_dir(name);
    let t0 = Instant::now();
    let (cap, exchanges) =
        runner::execute_with_plant(program, &out, 4, Box::new(plant), enabled).expect("run");
    let wall = t0.elapsed().as_secs_f64();
    let virt = cap.end_ns as f64 * 1e-9;
    eprintln!(
        "{name}: {virt:.3} s virtual in {wall:.2} s wall ({:.2} s per simulated s), {} samples; \
         instructions: sampler {}, AC period {}, pulse end {}, frame {}",
        wall / virt,
        exchanges.len(),
        runner::stats(&cap.handlers[2].1),
        runner::stats(&cap.handlers[3].1),
        runner::stats(&cap.handlers[1].1),
        runner::stats(&cap.handlers[0].1),
    );
    let log = std::fs::read_to_string(out.join(cosim::AC_LOG)).expect("ac.log");
    let records = cosim::parse_ac_log(&log).expect("parse ac.log");
    Run {
        cap,
        exchanges,
        log,
        records,
    }
}

/// Position after every rising edge in the capture: (time ns, position).
fn vcd_path(pins: &[(u64, u8)]) -> Vec<(u64, [i64; 3])> {
    let mut p = [0i64; 3];
    let mut out = vec![(0, p)];
    for e in analysis::edges(0, pins).edges {
        p[e.axis] += i64::from(e.dir);
        out.push((e.t_ns, p));
    }
    out
}

/// (b): every request's encoder counts are a position the pins showed within half a millisecond
/// of the sample's nominal time (index + 1) ms (the sample timer starts in init, microseconds
/// after reset).
fn check_encoder_against_vcd(r: &Run) {
    let path = vcd_path(&r.cap.pins);
    for x in &r.exchanges {
        let t = (u64::from(x.index) + 1) * 1_000_000;
        let (lo, hi) = (t.saturating_sub(500_000), t + 500_000);
        let before = path.iter().rev().find(|(tt, _)| *tt <= lo).map(|p| p.1);
        let ok = before == Some(x.pos_blu)
            || path
                .iter()
                .any(|(tt, p)| *tt > lo && *tt <= hi && *p == x.pos_blu);
        assert!(
            ok,
            "sample {} at {:?} not on the VCD path",
            x.index, x.pos_blu
        );
    }
}

/// (e): the same samples, grouped per period, give the same decisions on the host.
fn check_host_replay(r: &Run) {
    let s = AcSettings::default();
    let n = (s.sample_hz * s.period_ms / 1000) as usize;
    assert!(!r.records.is_empty());
    let host = millac_qemu::emulator::cosim::replay(
        &r.records,
        &r.exchanges,
        &millac::Settings::default(),
        s,
    )
    .unwrap();
    for (k, (rec, o)) in r.records.iter().zip(&host).enumerate() {
        assert_eq!(rec.t_ms, (k as u64 + 1) * u64::from(s.period_ms));
        for x in &r.exchanges[k * n..(k + 1) * n] {
            assert_eq!(x.index as usize / n, k);
        }
        assert_eq!(o.feed_cap, rec.feed_cap, "period {k}");
        assert_eq!(o.e.to_bits(), rec.e.to_bits(), "period {k}");
        assert_eq!(o.f_n.to_bits(), rec.f_n.to_bits(), "period {k}");
        assert_eq!(o.t_nm.to_bits(), rec.t_nm.to_bits(), "period {k}");
        assert_eq!(rec.overruns, 0, "period {k}");
    }
}

#[test]
fn ac_converges_to_f0_exact_end_deterministic_and_replayable() {
    let a = run("enabled-a", PROGRAM, Toy::new(25.0, None), true);
    assert_eq!(a.cap.status, Some(0), "{}", a.cap.stdout);
    // (a) exact end point, firmware and pins.
    assert_eq!(
        runner::firmware_position(&a.cap.result),
        Some([END_X, 0, 0]),
        "{}",
        a.cap.stdout
    );
    assert_eq!(vcd_path(&a.cap.pins).last().unwrap().1, [END_X, 0, 0]);
    // (a) the measured force settles on F0: the periods from 1 s on while cutting. The default
    // law (GPC) regulates on F0 itself (the paper's FRC settled below it, in its dead zone), so
    // the band is the toy plant's resolution: its force is the travel over a 10 ms window in
    // whole BLU, and one BLU more or less is a quantum of F0 / (BLU per window at the F0 feed),
    // 2.4 % at 25 ipm. The law dithers between 40 and 43 BLU per window (a feed change reaches the
    // window a period late): every settled period within 2 quanta, the mean within half a quantum.
    let f0 = AcSettings::default().f0_n();
    let quantum = 1.0 / (25.0 * 10_000.0 / 60.0 * 0.010);
    let settled: Vec<&AcRecord> = a
        .records
        .iter()
        .filter(|r| r.t_ms >= 1000 && r.pos_blu[0] < END_X - 200)
        .collect();
    assert!(settled.len() >= 20, "{} settled periods", settled.len());
    for r in &settled {
        assert!(
            (r.f_n / f0 - 1.0).abs() <= 2.0 * quantum,
            "t {} ms: F {} N, F0 {f0} N",
            r.t_ms,
            r.f_n
        );
        assert!(r.hold.is_none());
    }
    let mean = settled.iter().map(|r| r.f_n).sum::<f32>() / settled.len() as f32;
    assert!(
        (mean / f0 - 1.0).abs() <= 0.5 * quantum,
        "mean F {mean} N, F0 {f0} N"
    );
    // The feed was capped: slower than the programmed 30 ipm (feed number 3000).
    assert!(settled.iter().all(|r| r.feed_cap < 3000));
    check_encoder_against_vcd(&a);
    check_host_replay(&a);
    // (c) determinism.
    let b = run("enabled-b", PROGRAM, Toy::new(25.0, None), true);
    assert_eq!(a.exchanges, b.exchanges);
    assert_eq!(a.log, b.log);
    assert_eq!(a.cap.pins, b.cap.pins);
}

#[test]
fn stuck_sensor_holds_without_losing_a_pulse_and_the_run_ends() {
    let r = run("stuck", PROGRAM, Toy::new(25.0, Some(300)), true);
    // (d) hold: alarm logged and reported, cap 0, motion stops, the firmware reports and exits
    // (failure).
    assert_eq!(r.cap.status, Some(1), "{}", r.cap.stdout);
    assert!(
        r.cap.stdout.contains("warn: alarm: sensor hold"),
        "{}",
        r.cap.stdout
    );
    assert!(
        r.cap.result.contains("alarm: sensor hold"),
        "{}",
        r.cap.result
    );
    assert!(r.cap.result.contains("millac: hold"), "{}", r.cap.result);
    let first_hold = r
        .records
        .iter()
        .position(|x| x.hold.is_some())
        .expect("no hold in ac.log");
    assert!(r.records[first_hold..].iter().all(|x| x.feed_cap == 0));
    let fw = runner::firmware_position(&r.cap.result).expect("position line");
    let vcd = vcd_path(&r.cap.pins).last().unwrap().1;
    let enc = r.exchanges.last().unwrap().pos_blu;
    assert_eq!(fw, vcd, "firmware counters vs pins");
    assert_eq!(fw, enc, "firmware counters vs encoder");
    assert_eq!(r.records.last().unwrap().pos_blu, enc);
    assert!(fw[0] > 0 && fw[0] < END_X, "{fw:?}");
    // Nothing moved for the last second of the hold.
    let held = &r.records[r.records.len() - 100..];
    assert!(held.iter().all(|x| x.pos_blu == enc));
    check_encoder_against_vcd(&r);
    check_host_replay(&r);
}

/// The host side of the ADC goes away in the cut (its thread dies and the pipes close): the
/// firmware says so once, holds (no fresh samples), and the run ends as after any hold, with the
/// exact position (firmware, pins and last log line agree) and exit status 1; before, it exited at
/// once with no position.
#[test]
fn a_lost_adc_holds_and_reports_like_any_hold() {
    let mut plant = Toy::new(25.0, None);
    plant.gone_from = Some(300);
    let r = run("lost", PROGRAM, plant, true);
    assert_eq!(r.cap.status, Some(1), "{}", r.cap.stdout);
    let out = &r.cap.stdout;
    assert!(out.contains("error: simulated ADC lost"), "{out}");
    assert!(r.cap.result.contains("error: simulated ADC lost"), "{out}");
    let hold = runner::firmware_hold(&r.cap.result).expect("a hold report");
    assert_eq!(hold.alarm, "sensor hold: no fresh samples in an AC period");
    let vcd = vcd_path(&r.cap.pins).last().unwrap().1;
    assert_eq!(hold.position, vcd, "firmware counters vs pins");
    assert_eq!(r.records.last().unwrap().pos_blu, vcd);
    assert!(vcd[0] > 0 && vcd[0] < END_X, "{vcd:?}");
    assert_eq!(hold.blocks_done, 0);
    // Held at the first period without samples; the feed ramps down at the acceleration (at most
    // from q0, the highest feed number: q0 / (a q0 / W0^2) = W0^2 / a frames), nothing moves
    // after that.
    let first = r.records.iter().position(|x| x.hold.is_some()).unwrap();
    assert!(r.records[first].t_ms <= 320, "{:?}", r.records[first]);
    let s = Settings::default();
    let ramp_ms = (s.frame_hz as u64 * 1000).div_ceil(s.accel_blu_s2[0] as u64);
    let stopped = r
        .records
        .iter()
        .position(|x| x.t_ms >= r.records[first].t_ms + ramp_ms + 10)
        .unwrap();
    assert!(r.records[stopped..].iter().all(|x| x.pos_blu == vcd));
    assert!(
        r.records[first].pos_blu != vcd,
        "it ramped down, not a stop at once"
    );
}

#[test]
fn measure_only_leaves_the_pulses_equal_to_the_host_core() {
    let program = "G20 G91\nG1 X0.05 Y0.02 F30\nG2 X0.02 Y0 I0.01 J0 F20\nM2\n";
    let r = run("no-ac", program, Toy::new(25.0, None), false);
    assert_eq!(r.cap.status, Some(0), "{}", r.cap.stdout);
    let settings = millac::Settings::default();
    let prog = analysis::load_program(program, &settings).unwrap();
    let e = analysis::edges(0, &r.cap.pins);
    assert_eq!(
        analysis::compare_with_host(&prog, &settings, &e.groups),
        None
    );
    assert!(!r.records.is_empty());
    check_encoder_against_vcd(&r);
    check_host_replay(&r);
}
