//! The chatter re-plan on the core's frame (host): a chatter hold in a slot is re-planned into a
//! lifted pass and a lower layer, again while it chatters, and refused where it cannot be.
use super::*;
use crate::gcode::tape::Tape;
use crate::nc::Frame;
use crate::protocol::codes::ac_alarm;
use crate::rt::ac::AC_RUN;
use crate::rt::status::{Status, Writers};

const PROGRAM: &str = "G20 G90\nG0 X0 Y0\nG0 Z-0.35\nG1 X1.0 F20\nG1 Y0.5\nG1 X0\nG0 Z0.1\nM2\n";

fn blocks(text: &str, nc: Settings) -> Vec<Sealed> {
    let mut tape = Tape::new(nc);
    let mut out = Vec::new();
    tape.feed(text.as_bytes(), |b| out.push(b)).unwrap();
    tape.finish(|b| out.push(b)).unwrap();
    out
}

/// A frame, its queue and status, the loader's record, and a stand-in for the AC: a chatter
/// hold is a feed cap of 0 until the loader asks the AC to resume.
struct Rig {
    frame: Frame,
    q: HostQueue,
    status: &'static Status,
    w: Writers<'static, &'static Status>,
    replan: Replan<12>,
    program: std::collections::VecDeque<Sealed>,
    trace: Vec<[i32; 3]>,
    events: Vec<Event>,
}

impl Rig {
    fn new(text: &str, nc: Settings, lift_mm: f32) -> Rig {
        let status: &'static Status = Box::leak(Box::new(Status::new()));
        let w = status.split();
        w.ac.set_state(AC_RUN);
        Rig {
            frame: Frame::new(FrameConfig::from_settings(&nc)),
            // A small queue: the blocks behind a held one are more than it holds.
            q: HostQueue {
                blocks: Default::default(),
                cap: 3,
            },
            status,
            w,
            replan: Replan::new(
                nc,
                &AcSettings {
                    chatter_step_mm: lift_mm,
                    ..AcSettings::default()
                },
                [0; 3],
            ),
            program: blocks(text, nc).into(),
            trace: vec![[0; 3]],
            events: Vec::new(),
        }
    }

    /// One frame with the loader's and the AC's turns.
    fn step(&mut self) {
        while let Some(b) = self.program.pop_front() {
            if let Err(b) = self.replan.offer(&mut self.q, b) {
                self.program.push_front(b);
                break;
            }
        }
        let held = self.status.ac_state.get() != AC_RUN;
        let cap = if held { 0 } else { u32::MAX };
        let word = self.status.operator.get();
        self.frame
            .tick(&mut self.q, (cap, word, crate::ports::PLAN_ONE));
        self.w.frame.publish_all(&self.frame);
        if self.trace.last() != Some(&self.frame.position()) {
            self.trace.push(self.frame.position());
        }
        if self.w.ac.take_resume() {
            self.w.ac.set_state(AC_RUN);
            self.w.ac.count_resume();
        }
        match self.replan.poll(&mut self.q, &self.w.loader) {
            Event::None => {}
            Event::Speed(s) => {
                // The loader's part: the spindle takes it, then the AC resumes.
                self.replan.speed_applied(&self.w.loader, s.to);
                self.events.push(Event::Speed(s));
            }
            e => self.events.push(e),
        }
    }

    fn chatter(&self) {
        let a = crate::ac::Alarm::Chatter {
            freq_hz: 1680.0,
            amplitude: 9.0,
            threshold: 1.0,
        };
        // As the AC period publishes a chatter hold: its frequency, then the state.
        self.w.ac.set_chatter_hz(1680.0);
        self.w.ac.set_state(ac_alarm(&a));
    }

    fn done(&self) -> bool {
        self.program.is_empty()
            && !self.replan.pending()
            && self.q.queued() == 0
            && self.frame.idle()
    }

    /// Runs to the end; `hold_when` says at which positions the chatter monitor holds.
    fn run(&mut self, mut hold_when: impl FnMut([i32; 3]) -> bool) {
        for _ in 0..10_000_000 {
            if self.done() {
                return;
            }
            if self.status.ac_state.get() == AC_RUN && hold_when(self.frame.position()) {
                self.chatter();
            }
            self.step();
        }
        panic!("the program did not end");
    }
}

const Z1: i32 = -3500;
const LIFT: i32 = 394; // 1 mm in 0.0001 in

/// The XY positions (x of the first slot) visited at height `z`.
fn xs_at(trace: &[[i32; 3]], z: i32) -> Vec<i32> {
    trace
        .iter()
        .filter(|p| p[2] == z && p[1] == 0)
        .map(|p| p[0])
        .collect()
}

#[test]
fn a_chatter_hold_is_replanned_into_a_lifted_pass_and_a_lower_layer() {
    let nc = Settings::default();
    let plain = {
        let mut r = Rig::new(PROGRAM, nc, 1.0);
        r.run(|_| false);
        (r.frame.position(), r.frame.blocks_done(), r.trace)
    };
    let mut r = Rig::new(PROGRAM, nc, 1.0);
    let mut once = false;
    r.run(|p| {
        let hit = !once && p[2] == Z1 && p[0] >= 4000;
        once |= hit;
        hit
    });
    assert_eq!(r.frame.position(), plain.0, "ends where the program ends");
    assert_eq!(
        r.frame.blocks_done(),
        plain.1 + 4,
        "a detour is five blocks for one"
    );
    let [Event::Replanned(e)] = r.events[..] else {
        panic!("one re-plan: {:?}", r.events);
    };
    assert_eq!(e.lift, LIFT as u32);
    assert_eq!(e.to, [10_000, 0, Z1]);
    assert_eq!(e.at[2], Z1);
    assert!((4000..5000).contains(&e.at[0]), "stopped at {:?}", e.at);
    // The rest of the block at the reduced depth, from the stop to its end...
    // (The plunge passes that height at x 0.)
    let upper = xs_at(&r.trace, Z1 + LIFT);
    assert_eq!(upper.iter().filter(|&&x| x > 0).min(), Some(&e.at[0]));
    assert!(upper.contains(&10_000));
    // ...and every x of the slot at full depth (the first part before the hold, the layer after).
    let lower = xs_at(&r.trace, Z1);
    for x in 0..=10_000 {
        assert!(lower.contains(&x), "x {x} never cut at z {Z1}");
    }
    // The layer after the upper pass: the last visit of the slot's end at full depth comes after
    // the upper pass.
    let last_upper = r.trace.iter().rposition(|p| *p == [10_000, 0, Z1 + LIFT]);
    let last_lower = r.trace.iter().rposition(|p| *p == [10_000, 0, Z1]);
    assert!(last_lower > last_upper);
    // Nothing else changed: the plain run's path is a sub-sequence of this one's.
    assert!(r.trace.len() > plain.2.len());
}

#[test]
fn chatter_in_the_lifted_pass_lifts_it_again() {
    let nc = Settings::default();
    let mut r = Rig::new(PROGRAM, nc, 1.0);
    let (mut first, mut second) = (false, false);
    r.run(|p| {
        if !first && p[2] == Z1 && p[0] >= 3000 {
            first = true;
            return true;
        }
        if first && !second && p[2] == Z1 + LIFT && p[0] >= 6000 {
            second = true;
            return true;
        }
        false
    });
    let [Event::Replanned(a), Event::Replanned(b)] = r.events[..] else {
        panic!("two re-plans: {:?}", r.events);
    };
    assert_eq!(b.count, 2);
    assert_eq!(a.to, [10_000, 0, Z1]);
    assert_eq!(b.at[2], Z1 + LIFT);
    assert_eq!(
        b.to,
        [10_000, 0, Z1 + LIFT],
        "the held block is the upper pass"
    );
    // Three levels: the twice-lifted pass from the second stop, and both layers below to the end.
    let top = xs_at(&r.trace, Z1 + 2 * LIFT);
    assert_eq!(top.iter().filter(|&&x| x > 0).min(), Some(&b.at[0]));
    for z in [Z1, Z1 + LIFT, Z1 + 2 * LIFT] {
        assert!(xs_at(&r.trace, z).contains(&10_000), "z {z}");
    }
    let plain = {
        let mut r = Rig::new(PROGRAM, nc, 1.0);
        r.run(|_| false);
        r.frame.position()
    };
    assert_eq!(r.frame.position(), plain);
}

#[test]
fn holds_that_cannot_be_replanned_stay_holds() {
    let nc = Settings::default();
    // An arc, a ramp, and a lift past the Z soft limit.
    let arc = "G20 G90\nG0 X0 Y0\nG0 Z-0.35\nG2 X1 Y0 I0.5 J0 F20\nG0 Z0.1\nM2\n";
    let ramp = "G20 G90\nG0 X0 Y0\nG0 Z-0.35\nG1 X1 Z-0.4 F20\nG0 Z0.1\nM2\n";
    let low = Settings {
        soft_max: [100_000, 100_000, Z1 + LIFT - 1],
        ..nc
    };
    let under = "G20 G90\nG0 Z-0.35\nG0 X0 Y0\nG1 X1.0 F20\nG0 Z-0.32\nM2\n";
    for (text, nc, why) in [
        (arc, nc, Refusal::NotLinear),
        (ramp, nc, Refusal::MovesZ),
        (
            under,
            low,
            Refusal::SoftLimit {
                z: Z1 + LIFT,
                max: Z1 + LIFT - 1,
            },
        ),
    ] {
        let mut r = Rig::new(text, nc, 1.0);
        let mut once = false;
        for _ in 0..2_000_000 {
            if !once && r.frame.position()[2] <= Z1 && r.frame.position()[0] >= 2000 {
                once = true;
                r.chatter();
            }
            r.step();
            if !r.events.is_empty() {
                break;
            }
        }
        assert!(
            matches!(r.events[..], [Event::Refused { why: w, .. }] if w == why),
            "{why:?}: {:?}",
            r.events
        );
        // The machine stands held, its queue kept, no abort.
        let at = r.frame.position();
        for _ in 0..1000 {
            r.step();
        }
        assert_eq!(r.frame.position(), at);
        assert!(r.q.queued() > 0);
        assert_eq!(r.status.operator.get() & operator::ABORT, 0);
    }
}

#[test]
fn without_a_step_a_chatter_hold_stays_a_hold() {
    let mut r = Rig::new(PROGRAM, Settings::default(), 0.0);
    let mut once = false;
    for _ in 0..2_000_000 {
        if !once && r.frame.position() == [4000, 0, Z1] {
            once = true;
            r.chatter();
        }
        r.step();
    }
    assert!(once);
    assert!(r.events.is_empty());
    assert!(!r.done());
    assert_eq!(r.frame.position()[2], Z1);
}

#[test]
fn the_detour_ends_at_the_held_blocks_end() {
    let nc = Settings::default();
    let cfg = FrameConfig::from_settings(&nc);
    let b = blocks("G20 G91\nG1 X1 Y-0.5 F20\n", nc)[0];
    let (pc, p1) = ([3000, -1500, -200], [10_000, -5000, -200]);
    let path = detour(&b, pc, p1, 100, &nc, &cfg).unwrap();
    assert_eq!(path.len(), DETOUR);
    let mut p = pc;
    let mut levels = Vec::new();
    for b in &path {
        let d = displacement(b);
        p = [0, 1, 2].map(|k| p[k] + d[k]);
        levels.push(p);
    }
    assert_eq!(
        levels,
        vec![
            [3000, -1500, -100],
            [10_000, -5000, -100],
            [3000, -1500, -100],
            [3000, -1500, -200],
            [10_000, -5000, -200],
        ]
    );
    // The cuts keep the block's feed; both are sealed (a ramp, so they start).
    for b in [path[1], path[4]] {
        let (Motion::Linear(l), Motion::Linear(orig)) = (
            b.motion,
            &blocks("G20 G91\nG1 X1 Y-0.5 F20\n", nc)[0].motion,
        ) else {
            panic!("a cut is a line");
        };
        assert_eq!(l.f, orig.f);
        assert!(l.ramp > 0);
    }
    // Nothing left in XY: nothing to do.
    assert!(detour(&b, p1, p1, 100, &nc, &cfg).unwrap().is_empty());
}

#[test]
fn a_chattering_layer_is_split_in_halves_never_lifted_into_air() {
    let nc = Settings::default();
    let mut r = Rig::new(PROGRAM, nc, 1.0);
    let (mut first, mut in_layer) = (None::<i32>, 0);
    r.run(|p| {
        // The first hold in the programmed pass; then every lower pass at Z1 (a layer of known
        // thickness) chatters once it has moved 500 BLU, three times.
        if first.is_none() && p[2] == Z1 && p[0] >= 3000 {
            first = Some(p[0]);
            return true;
        }
        if let Some(x0) = first {
            if in_layer < 3 && p[2] == Z1 && p[1] == 0 && p[0] >= x0 + 500 * (in_layer + 1) {
                in_layer += 1;
                return true;
            }
        }
        false
    });
    let steps: Vec<u32> = r
        .events
        .iter()
        .map(|e| match e {
            Event::Replanned(p) => p.lift,
            e => panic!("{e:?}"),
        })
        .collect();
    // 394 (1 mm) for the programmed pass; the 394 BLU layer halves: 197, then 98, then 49.
    assert_eq!(steps, vec![394, 197, 98, 49]);
    assert_eq!(step(98, 394), Some(49));
    assert_eq!(
        step(79, 394),
        None,
        "halves below {MIN_LAYER_BLU} BLU are refused"
    );
    // Every level was cut down to Z1 over the whole slot, and the program ended where it ends.
    for x in 0..=10_000 {
        assert!(xs_at(&r.trace, Z1).contains(&x), "x {x}");
    }
    let plain = {
        let mut p = Rig::new(PROGRAM, nc, 1.0);
        p.run(|_| false);
        p.frame.position()
    };
    assert_eq!(r.frame.position(), plain);
}

/// `$277`: a chatter hold changes the spindle speed to the nearest stable lobe and the block goes
/// on (no re-plan); a second hold in the same block takes the rule's next speed from the speed it
/// reached; a third is the depth step's (or, without one, an alarm); a new block may change the
/// speed again.
#[test]
fn the_spindle_speed_comes_first_then_the_depth_steps() {
    let nc = Settings::default();
    let rig = |lift_mm: f32| {
        let mut r = Rig::new(PROGRAM, nc, lift_mm);
        r.replan = Replan::new(
            nc,
            &AcSettings {
                chatter_step_mm: lift_mm,
                chatter_max_rpm: 30_000,
                ..AcSettings::default()
            },
            [0; 3],
        );
        r.w.loader.set_spindle_rpm(14_000);
        r
    };
    let plain = {
        let mut r = rig(1.0);
        r.run(|_| false);
        r.frame.blocks_done()
    };
    // Holds at x 0.3, 0.5 and 0.7 in in the slot (line 4), and one in the next block (line 5).
    let holds = |r: &mut Rig| {
        let mut at = vec![(3000, 0), (5000, 0), (7000, 0), (10_000, 2000)];
        r.run(move |p| match at.first() {
            Some(&(x, y)) if p[2] == Z1 && p[0] >= x && p[1] >= y => {
                at.remove(0);
                true
            }
            _ => false,
        });
    };
    let mut r = rig(1.0);
    holds(&mut r);
    let speeds: Vec<SpeedChange> = r
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Speed(s) => Some(*s),
            _ => None,
        })
        .collect();
    // 1680 Hz with 4 flutes at 14 000 rpm: ratio 1.8, m = 2: 12 600 rpm. At 12 600 the ratio is
    // 2.0 (no change there): the nearest other lobe, m = 3, 8400 rpm; in line 5 from 8400 (ratio
    // 3.0) m = 4, 6300 rpm.
    assert!(
        matches!(
            r.events[..],
            [
                Event::Speed(_),
                Event::Speed(_),
                Event::Replanned(_),
                Event::Speed(_)
            ]
        ),
        "{:?}",
        r.events
    );
    assert_eq!(
        speeds
            .iter()
            .map(|s| (s.from, s.to, s.m, s.line, s.count))
            .collect::<Vec<_>>(),
        [
            (14_000, 12_600, 2, 4, 1),
            (12_600, 8400, 3, 4, 2),
            (8400, 6300, 4, 5, 3)
        ]
    );
    assert_eq!(speeds[0].chatter_hz, 1680);
    assert!((3000..3100).contains(&speeds[0].at[0]), "{:?}", speeds[0]);
    // The speed stays (the monitors judge at it).
    assert_eq!(r.status.spindle_rpm.get(), 6300);
    // One detour (four more blocks), for the third hold in the slot.
    assert_eq!(r.frame.blocks_done(), plain + 4);
    // Without a depth step the third hold in the block stays a hold.
    let mut r = rig(0.0);
    let mut at = vec![3000, 5000, 7000];
    let mut refused = None;
    for _ in 0..10_000_000 {
        if let Some(Event::Refused { why, .. }) = r.events.last() {
            refused = Some(*why);
            break;
        }
        if r.status.ac_state.get() == AC_RUN
            && at
                .first()
                .is_some_and(|&x| r.frame.position()[2] == Z1 && r.frame.position()[0] >= x)
        {
            at.remove(0);
            r.chatter();
        }
        r.step();
    }
    assert_eq!(refused, Some(Refusal::NoSpeed), "{:?}", r.events);
    assert_eq!(r.events.len(), 3);
    assert!(r.status.ac_state.get() != AC_RUN, "still held");
}
