//! The papers' feed-law experiments on the simulated cut (host, issue 9): each test runs a
//! scenario of `millac_qemu::evaluation::repro` for every strategy (the same runs as the `ac_repro`
//! example's figures and tables) and asserts the behaviour the figure shows. Thresholds: a law
//! "oscillates" when F/F0 swings by more than 0.5 (half the reference) peak to peak over the last
//! second of a section, and is "settled" below 0.1 (the +-5 % band).
use millac::ac::law::Strategy;
use millac_qemu::evaluation::repro::{self, Trace};

fn by(traces: &[Trace], s: Strategy) -> &Trace {
    traces.iter().find(|t| t.strategy == s).unwrap()
}

/// Ulsoy, Koren and Lauderbaugh's Figs. 2-3 on the simulated cut: a slot whose depth steps
/// 1 -> 2 -> 3 mm, every law tuned at 1 mm (`$264` = the feed at F0 at 1 mm, measured).
///
/// - The integral law with the papers' pole assignment (k_i b = 1.1 on their model) oscillates
///   already at 1 mm here: the simulated loop has about two periods more lag (the DRR's 3-window
///   held peak); see `repro::INTEGRAL_DETUNE`. With a quarter of that gain it settles at 1 and
///   2 mm and oscillates at 3 mm, a sustained cycle to the section's end: their Fig. 2.
/// - The paper's FRC, a fixed-gain law too, settles at 1 and 2 mm; at 3 mm it is at the edge of
///   its stability: entered from the start hole at FRM it cycled to the section's end
///   (peak to peak 0.96), entered at the program's conservative F8 it settles in its dead zone
///   (0.954 F0). Not asserted at 3 mm.
/// - MRAC and GPC (adaptive) stay settled at every depth (their Fig. 3): from 1 s after each step
///   MRAC and GPC within 0.25 of F0 (measured 0.15 and 0.12 at 3 mm: isolated dips; GPC at
///   its default lambda 10); both within 0.1 peak to peak over the last second of the 1 and 2 mm
///   sections and within 3 % of F0 on average. At 3 mm the band is the stepper's: at about
///   6.4 ipm a tooth period's travel is 27 or 28 whole BLU, so the held peaks move in steps of
///   3.5 % of F0, and over the last second MRAC wanders over 3 to 6 of them (peak to peak 0.106 to 0.212
///   over the noise seeds 1 to 8, as much with the plant before issue 20's chip as after; seed 1
///   read 0.071 before and 0.141 after), GPC over 1 to 3: settled there is below 0.25.
#[test]
fn depth_step_fixed_gains_oscillate_at_3_mm_adaptive_laws_stay_settled() {
    let (sc, nominal) = repro::depth_step().unwrap();
    println!("$264 for 1 mm: {nominal:.2} ipm");
    let traces = sc.run_all().unwrap();
    let detuned = repro::depth_step_integral_detuned(&sc, nominal).unwrap();
    let figs = |tr: &Trace| {
        let f = repro::depth_figures(tr);
        for (d, x) in f.iter().enumerate() {
            println!("{} at {} mm: {x:?}", tr.name, d + 1);
        }
        f
    };

    let f = figs(by(&traces, Strategy::Integral));
    assert!(f[0].ptp_last > 0.5, "papers' tuning at 1 mm: {:?}", f[0]);

    let f = figs(&detuned);
    assert!(!detuned.run.held);
    assert!(f[0].ptp_last < 0.1 && f[1].ptp_last < 0.1, "{f:?}");
    assert!(f[2].ptp_last > 0.5, "3 mm: {:?}", f[2]);

    let paper = by(&traces, Strategy::Paper);
    let f = figs(paper);
    assert!(!paper.run.held);
    assert!(f[0].ptp_last < 0.1 && f[1].ptp_last < 0.1, "{f:?}");

    for (s, band) in [(Strategy::Mrac, 0.25), (Strategy::Gpc, 0.25)] {
        let tr = by(&traces, s);
        assert!(!tr.run.held, "{}", tr.name);
        for (d, x) in figs(tr).iter().enumerate() {
            assert!(x.worst < band, "{} at {} mm: {x:?}", tr.name, d + 1);
            let settled = if d == 2 { 0.25 } else { 0.1 };
            assert!(x.ptp_last < settled, "{} at {} mm: {x:?}", tr.name, d + 1);
            assert!((x.mean_last - 1.0).abs() < 0.03, "{} {x:?}", tr.name);
        }
    }
}

/// The GPC's steady gain B(1)/A(1) at a period.
fn gpc_gain(tr: &Trace, k: usize) -> f64 {
    let [a1, a2, b0, b1, b2] = tr.run.rows[k].estimates.unwrap().map(f64::from);
    (b0 + b1 + b2) / (1.0 + a1 + a2)
}

/// The thesis' test TIIM (depth 7.62 -> 10.5 mm, +38 %) in steel with the 0.5 in cutter, the
/// overload hold moved out of the way (as the thesis' controller had none). The step reaches
/// about 1.38 x the settled force within a tooth, before a 10 ms loop can act: every law
/// overshoots past the default hold (1.1 F0). The paper's FRC, MRAC and GPC then settle to
/// +-5 % of F0 within 1 s (measured 0.25, 0.35, 0.75 s); the integral law (default `$264`, 15 ipm:
/// k_i g above the delay-2 limit, see `repro::INTEGRAL_DETUNE`) cycles for the whole cut. The
/// GPC's estimated steady gain follows the deeper cut (as the thesis' Fig. 5.11 shows its
/// estimates move at a change of the process).
#[test]
fn tiim_step_overshoots_every_law_and_the_adaptive_ones_settle_within_1_s() {
    let traces = repro::tiim().run_all().unwrap();
    for tr in &traces {
        let s = repro::tiim_response(tr);
        println!("{}: {s:?}", tr.name);
        assert!(!tr.run.held, "{}", tr.name);
        assert!(s.peak > repro::DEFAULT_HOLD_LOAD, "{}: {s:?}", tr.name);
        if tr.strategy == Strategy::Integral {
            assert!(s.settling_s > 5.0, "{s:?}");
        } else {
            assert!(s.settling_s < 1.0, "{}: {s:?}", tr.name);
            // The paper's FRC settles anywhere in its dead zone, up to 3.7 % below F0.
            let below = if tr.strategy == Strategy::Paper {
                0.045
            } else {
                0.03
            };
            assert!(
                s.final_level > 1.0 - below && s.final_level < 1.03,
                "{}: {s:?}",
                tr.name
            );
        }
    }
    let gpc = by(&traces, Strategy::Gpc);
    let step = gpc.span_x(repro::TIIM_STEP_X - repro::STEP_MARGIN_IN, 4.4);
    let (before, after) = (gpc_gain(gpc, step.start - 1), gpc_gain(gpc, step.end - 1));
    println!("GPC B(1)/A(1): {before:.3} before the step, {after:.3} at the end");
    assert!(after > 1.2 * before, "{before} -> {after}");
}

/// The pocket after the thesis' Fig. 5.8, default settings: the paper's FRC and GPC finish it
/// without a hold (GPC within 1.05 F0 at its peaks, the thesis' corners showed 25 %); the
/// integral law (default `$264`) holds on an overload in the first wall, MRAC at the first
/// corner: after the stop the cut along +Y is a slot whose engagement grows from half to full
/// over the tool's radius (the first wall's slot side lies R beyond its path), MRAC reads the
/// light windows after the corner and raises the feed by the full step, and the growing
/// engagement takes a window to 1.15 F0. (MRAC finished while the plant's probe read that side
/// wall up to 2 mm early, a full chip where there was air: issue 20.) GPC's estimates move
/// during the run (Fig. 5.11).
#[test]
fn pocket_adaptive_laws_finish_and_the_integral_law_holds() {
    let traces = repro::pocket().run_all().unwrap();
    for tr in &traces {
        let peak = tr.load.iter().cloned().fold(0.0, f64::max);
        println!(
            "{}: {:.2} s, peak {peak:.3} F0, held {}",
            tr.name, tr.run.machining_time_s, tr.run.held
        );
        match tr.strategy {
            Strategy::Integral | Strategy::Mrac => assert!(tr.run.held, "{}", tr.name),
            _ => {
                assert!(!tr.run.held, "{}", tr.name);
                assert!(peak < repro::DEFAULT_HOLD_LOAD, "{}: {peak}", tr.name);
            }
        }
    }
    let gpc = by(&traces, Strategy::Gpc);
    let first = gpc.run.rows[0].estimates.unwrap();
    let moved = gpc
        .run
        .rows
        .iter()
        .filter(|r| r.estimates != Some(first))
        .count();
    assert!(
        moved > gpc.run.rows.len() / 2,
        "{moved} of {}",
        gpc.run.rows.len()
    );
}

/// From air into a 0.3 in full slot and out again. At F22 (just above the 21.4 ipm at F0) no law
/// reaches the default hold at entry (the entry peak is the programmed over the F0 feed for
/// those that open the feed to F22 in air; MRAC waits in air at 8.4 ipm, its 0.5 / b^) and each
/// is back at 95 % of F22 within 0.1 s of the exit. At F30 every law's entry overshoots past
/// the hold (the first tooth sees 1.22 to 1.40 F0) and holds on an overload.
#[test]
fn entry_from_air_and_exit() {
    for feed in repro::ENTRY_FEEDS_IPM {
        for tr in repro::entry_exit(feed).run_all().unwrap() {
            let e = repro::entry_exit_figures(&tr, feed);
            println!("F{feed} {}: {e:?}", tr.name);
            if feed < 25.0 {
                assert!(!e.held, "{}", tr.name);
                assert!(
                    e.entry_peak < repro::DEFAULT_HOLD_LOAD,
                    "{}: {e:?}",
                    tr.name
                );
                assert!(e.recovery_s.is_some_and(|s| s <= 0.1), "{}: {e:?}", tr.name);
            } else {
                assert!(e.held, "{}", tr.name);
                assert!(matches!(
                    tr.run.alarm,
                    Some(millac::ac::Alarm::Overload { .. })
                ));
            }
        }
    }
}
