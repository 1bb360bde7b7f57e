//! Host tests of the dialect CAM programs use beyond motion: work offsets (G54-G59, G10, G92,
//! G53), stored positions (G28/G30), tools (T, M6, G43, G43.1, G49, G10 L1), stops (M0, M1),
//! inverse time (G93), and the codes accepted without effect or refused by name.
use super::*;
use crate::gcode::error::Construct;
use crate::nc::Rapid;

/// BLU per inch at the default settings (0.0001 in).
const IN: i64 = 10_000;

/// The machine position after each line of `lines` (each must be accepted).
fn run(p: &mut Parser, lines: &[&str]) -> [i32; 3] {
    for l in lines {
        p.line(1, l).unwrap_or_else(|e| panic!("{l:?}: {e}"));
    }
    p.position()
}

fn at(x: f64, y: f64, z: f64) -> [i32; 3] {
    [x, y, z].map(|v| (v * IN as f64).round() as i32)
}

#[test]
fn coordinate_systems_move_the_program_origin() {
    let mut p = parser();
    // G55's origin at (1, 2, -0.5) in: X0.5 Y0 Z0 there is machine (1.5, 2, -0.5).
    let pos = run(&mut p, &["G20 G10 L2 P2 X1 Y2 Z-0.5", "G55 G0 X0.5 Y0 Z0"]);
    assert_eq!(pos, at(1.5, 2.0, -0.5));
    assert_eq!(p.modes().coord, 1);
    // Increments do not see the origin.
    assert_eq!(run(&mut p, &["G91 X0.25", "G90"]), at(1.75, 2.0, -0.5));
    // G54 is still at the machine's origin.
    assert_eq!(run(&mut p, &["G54 X0 Y0"]), at(0.0, 0.0, -0.5));
    // P0 is the system in use; an axis without a word keeps its offset.
    assert_eq!(
        run(&mut p, &["G55", "G10 L2 P0 Y3", "X0 Y0"]),
        at(1.0, 3.0, -0.5)
    );
    // Metric words convert exactly: 25.4 mm is an inch.
    assert_eq!(
        run(&mut p, &["G21 G10 L2 P3 X25.4", "G57 X0", "G20"]),
        at(0.0, 3.0, -0.5)
    );
}

#[test]
fn g10_l20_makes_the_position_the_words() {
    let mut p = parser();
    run(&mut p, &["G20 G0 X1.5 Y2 Z-0.25"]);
    // The current position becomes (0, 0.5) in G54: its origin is (1.5, 1.5).
    run(&mut p, &["G10 L20 P1 X0 Y0.5"]);
    assert_eq!(
        p.offsets().systems[0][..2],
        [1.5, 1.5].map(|v| (v * 25.4e9) as i64)
    );
    assert_eq!(run(&mut p, &["X0.1 Y0"]), at(1.6, 1.5, -0.25));
    // With G92 and a tool length in force, L20 still makes the position the word.
    run(&mut p, &["G92 X0", "G43.1 Z0.1", "G10 L20 P1 X0.2 Z1"]);
    let pos = p.position();
    assert_eq!(
        run(&mut p, &["X0.2 Z1"]),
        pos,
        "the words name where the machine stands"
    );
}

#[test]
fn g92_shifts_suspends_restores_and_clears() {
    let mut p = parser();
    run(&mut p, &["G20 G0 X1 Y1"]);
    run(&mut p, &["G92 X0"]);
    assert_eq!(run(&mut p, &["X0.2"]), at(1.2, 1.0, 0.0));
    assert_eq!(run(&mut p, &["G92.2", "X0.2"]), at(0.2, 1.0, 0.0));
    assert_eq!(run(&mut p, &["G92.3", "X0.2"]), at(1.2, 1.0, 0.0));
    assert_eq!(run(&mut p, &["G92.1", "X0.2"]), at(0.2, 1.0, 0.0));
    // A soft reset clears G92 (grbl), keeps the stored systems and returns to G54.
    run(&mut p, &["G10 L2 P2 X5", "G55 G92 X0"]);
    p.reset_modes();
    assert_eq!(p.offsets().g92_applied(), [0; 3]);
    assert_eq!(p.offsets().systems[1][0], 5 * 25_400_000_000);
    assert_eq!(p.modes().coord, 0);
    assert_eq!(run(&mut p, &["G20 G55 G0 X0"]), at(5.0, 1.0, 0.0));
}

#[test]
fn g53_moves_in_machine_coordinates_for_one_line() {
    let mut p = parser();
    run(&mut p, &["G20 G10 L2 P1 X2 Y2", "G0 X0 Y0"]);
    assert_eq!(p.position(), at(2.0, 2.0, 0.0));
    assert_eq!(run(&mut p, &["G53 G0 X0.1"]), at(0.1, 2.0, 0.0));
    assert_eq!(
        run(&mut p, &["X0.1"]),
        at(2.1, 2.0, 0.0),
        "G53 is non-modal"
    );
    // In G91 too, G53's words are machine coordinates (grbl's absolute override; CNCjs's tool
    // change sends G53 moves whatever the distance mode); G91 stays for the next line.
    assert_eq!(run(&mut p, &["G53 G91 G0 X1"]), at(1.0, 2.0, 0.0));
    assert_eq!(run(&mut p, &["X0.5"]), at(1.5, 2.0, 0.0), "G91 in force");
    assert_rejected(&mut p, "G53 G2 X1 I1 F10", ErrorKind::G53Motion);
}

#[test]
fn g28_and_g30_go_home_through_the_intermediate_point() {
    let mut p = parser();
    run(
        &mut p,
        &[
            "G20 G0 X1 Y2 Z0.5",
            "G28.1",
            "G0 X3 Y3 Z1",
            "G30.1",
            "X0 Y0 Z0",
        ],
    );
    // Without axis words: one rapid straight to the stored position.
    match p.line(1, "G28").unwrap() {
        Parsed::Block(b) => assert!(matches!(b.motion, Motion::Rapid(_))),
        other => panic!("{other:?}"),
    }
    assert_eq!(p.position(), at(1.0, 2.0, 0.5));
    // With axis words: up 0.5 in Z first (G91), then home in Z only.
    run(&mut p, &["G0 X3"]);
    let (a, b) = match p.line(1, "G28 G91 Z0.5").unwrap() {
        Parsed::Two(a, b) => (a, b),
        other => panic!("{other:?}"),
    };
    let steps = |b: Block| match b.motion {
        Motion::Rapid(Rapid { steps, signs }) => (steps, signs & 0b100),
        m => panic!("{m:?}"),
    };
    assert_eq!(steps(a), ([0, 0, 5_000], 0b100));
    assert_eq!(steps(b), ([0, 0, 5_000], 0));
    assert_eq!(p.position(), at(3.0, 2.0, 0.5));
    // G30 to its own position (X, Y, Z all: no axis word).
    run(&mut p, &["G90 G30"]);
    assert_eq!(p.position(), at(3.0, 3.0, 1.0));
    // The stored positions are machine coordinates: an offset does not move them.
    run(&mut p, &["G90 G10 L2 P1 X5", "G0 X0"]);
    run(&mut p, &["G28"]);
    assert_eq!(p.position(), at(1.0, 2.0, 0.5));
    assert_rejected(&mut p, "G28.1 X1", ErrorKind::AxisWordsUnused { code: 281 });
    assert_rejected(&mut p, "G28 G1 X1", ErrorKind::AxisCommandConflict);
}

#[test]
fn tools_length_offsets_and_changes() {
    let mut p = parser();
    // Tool 3: 1.5 in long, 0.25 in radius.
    run(&mut p, &["G20 G10 L1 P3 Z1.5 R0.25"]);
    let t = *p.tools().get(3).unwrap();
    assert_eq!(
        (t.length_pm, t.diameter_pm),
        (38_100_000_000, 12_700_000_000)
    );
    // T3 M6: the machine stops for tool 3; the tool is loaded.
    assert_eq!(
        p.line(1, "T3 M6").unwrap(),
        Parsed::Stop(Stop::ToolChange { tool: 3 })
    );
    assert_eq!((p.loaded_tool(), p.modes().tool), (3, 3));
    assert_eq!(run(&mut p, &["G43 H3 G0 Z0"]), at(0.0, 0.0, 1.5));
    assert_eq!(run(&mut p, &["G49 Z0"]), at(0.0, 0.0, 0.0));
    // G43 without H: the tool in the spindle.
    assert_eq!(run(&mut p, &["G43 Z-1"]), at(0.0, 0.0, 0.5));
    assert_eq!(run(&mut p, &["G43.1 Z0.25", "Z0"]), at(0.0, 0.0, 0.25));
    assert_eq!(p.modes().tool_length, ToolLength::Dynamic);
    assert_rejected(&mut p, "G43.1 X1", ErrorKind::ToolLengthAxis);
    assert_rejected(&mut p, "T17", ErrorKind::ToolNumber { value: 17 });
    assert_rejected(&mut p, "T1.5", ErrorKind::NotInteger('T'));
    assert_rejected(&mut p, "G10 L1 P0 Z1", ErrorKind::ToolNumber { value: 0 });
    assert_rejected(
        &mut p,
        "T2 M6 G0 X1",
        ErrorKind::StopWithMotion { code: 60 },
    );
    // A refused G10 L1 leaves the table as it was.
    assert_rejected(&mut p, "G10 L1 P2 Z1 Q1", ErrorKind::UnusedWord('Q'));
    assert_eq!(p.tools().get(2).unwrap().length_pm, 0);
}

#[test]
fn stops_delimiters_and_accepted_modes() {
    let mut p = parser();
    assert_eq!(p.line(1, "M0").unwrap(), Parsed::Stop(Stop::Pause));
    assert_eq!(
        p.line(1, "M1").unwrap(),
        Parsed::Nothing,
        "M1 is ignored, as grbl"
    );
    assert_eq!(p.line(1, "%").unwrap(), Parsed::Nothing);
    assert_eq!(p.line(1, " % (start)").unwrap(), Parsed::Nothing);
    for l in [
        "G17 G21 G40 G49 G80 G90",
        "G61",
        "G61.1",
        "G64 P0.01 Q0.01",
        "G98",
        "G99",
        "N10 G94",
    ] {
        assert_eq!(p.line(1, l).unwrap(), Parsed::Nothing, "{l}");
    }
    assert_eq!(p.modes().retract, Retract::RPlane);
    run(&mut p, &["M7", "M8"]);
    assert_eq!(
        p.modes().coolant,
        Coolant {
            mist: true,
            flood: true
        }
    );
    run(&mut p, &["M9"]);
    assert_eq!(p.modes().coolant, Coolant::OFF);
    assert_rejected(
        &mut p,
        "M7 M8",
        ErrorKind::ModalConflict {
            letter: 'M',
            first: 70,
            second: 80,
        },
    );
    assert_rejected(
        &mut p,
        "G41 D1",
        ErrorKind::NotInDialect(Construct::CutterCompensation),
    );
    assert_rejected(
        &mut p,
        "G42",
        ErrorKind::NotInDialect(Construct::CutterCompensation),
    );
    assert_rejected(
        &mut p,
        "#1 = 5",
        ErrorKind::NotInDialect(Construct::Parameter),
    );
    assert_rejected(
        &mut p,
        "G1 X[1+2]",
        ErrorKind::NotInDialect(Construct::Expression),
    );
    assert_rejected(
        &mut p,
        "o100 sub",
        ErrorKind::NotInDialect(Construct::OWord),
    );
    assert_rejected(
        &mut p,
        "G59.1",
        ErrorKind::NotInDialect(Construct::G59Extended),
    );
    assert_rejected(
        &mut p,
        "G10 L10 P1 Z0",
        ErrorKind::NotInDialect(Construct::G10Form),
    );
    assert_rejected(&mut p, "G80 X1", ErrorKind::AxisWordsUnused { code: 800 });
    // The program's end returns to G54 (the offsets stay).
    run(&mut p, &["G20 G10 L2 P2 X1", "G55"]);
    assert_eq!(p.line(1, "M30").unwrap(), Parsed::End);
    p.end_program();
    assert_eq!(p.modes().coord, 0);
    assert_eq!(p.offsets().systems[1][0], 25_400_000_000);
}

#[test]
fn inverse_time_feeds_run_each_block_in_its_time() {
    let st = Settings::default();
    let mut p = parser();
    // 1 in in 1/2 minute is 2 in/min: the feed number of F2 in G94 inches.
    let l = linear(&mut p, "G20 G93 G1 X1 F2");
    assert_eq!(
        l.f,
        feed_number(&st, Decimal::int(2), st.blu.per_inch()).unwrap()
    );
    // A 2 in move in 1/2 minute runs twice as fast.
    let l = linear(&mut p, "X3 F2");
    assert_eq!(
        l.f,
        feed_number(&st, Decimal::int(4), st.blu.per_inch()).unwrap()
    );
    assert_rejected(&mut p, "X4", ErrorKind::InverseTimeNeedsF);
    // Back in G94 the feed is undefined until an F.
    assert_rejected(&mut p, "G94 X4", ErrorKind::NoFeed { code: 1 });
    run(&mut p, &["G94 F10 X4"]);
}

#[test]
fn a_zero_offset_normal_to_the_plane_is_accepted() {
    let mut p = parser();
    // FreeCAD's grbl post writes K0.000 on every G17 arc.
    assert!(matches!(
        motion(&mut p, "G20 G17 G2 X0.2 Y0 I0.1 J0 K0.000 F10"),
        Motion::Arc(_)
    ));
    assert_rejected(&mut p, "G2 X0 Y0 I-0.1 J0 K0.1", ErrorKind::UnusedWord('K'));
}

/// G38.2-G38.5: a G1 move to the target handed on as a probing move with what it waits for;
/// feed and axis words required, a move of at least a BLU; the motion mode is G80 afterwards
/// (axis words alone are refused, never a move); G38.0, G38.1 and G38.6 are no codes.
#[test]
fn probing_moves_are_g1_moves_that_wait_for_the_probe() {
    use crate::gcode::Probe;
    let mut p = Parser::new(Settings::default());
    let got = p.line(1, "G21 G91 G38.2 Z-10 F20").unwrap();
    let Parsed::Probe(b, kind) = got else {
        panic!("{got:?}")
    };
    assert_eq!(
        kind,
        Probe {
            toward: true,
            must_change: true
        }
    );
    match b.motion {
        crate::nc::Motion::Linear(l) => assert_eq!((l.steps, l.signs & 4), ([0, 0, 3937], 0)),
        m => panic!("{m:?}"),
    }
    assert_eq!(p.position(), [0, 0, -3937]);
    assert_eq!(p.modes().motion, crate::gcode::MotionMode::None);
    assert_rejected(&mut p, "Z-1", ErrorKind::AxisWordsUnused { code: 800 });
    for (code, toward, must) in [
        ("38.3", true, false),
        ("38.4", false, true),
        ("38.5", false, false),
    ] {
        let got = p.line(2, &std::format!("g{code} x1")).unwrap();
        assert!(
            matches!(got, Parsed::Probe(_, k) if k == Probe { toward, must_change: must }),
            "{code}: {got:?}"
        );
    }
    let mut p = Parser::new(Settings::default());
    assert_rejected(&mut p, "G38.2 Z-1", ErrorKind::NoFeed { code: 38 });
    assert_rejected(&mut p, "G38.2 F10", ErrorKind::NoAxisWords { code: 380 });
    assert_rejected(&mut p, "G90 G38.2 Z0 F10", ErrorKind::ProbeTarget);
    assert_rejected(
        &mut p,
        "G38.2 G1 Z-1 F10",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 382,
            second: 10,
        },
    );
    for bad in ["G38.1 Z-1 F10", "G38.6 Z-1 F10", "G38 Z-1 F10"] {
        assert!(p.line(3, bad).is_err(), "{bad}");
    }
}

/// G91.1 (arc centres from the start: millac's only mode) is accepted and changes nothing, also
/// beside G91 on one line (its own modal group); G90.1 is refused naming itself.
#[test]
fn g91_1_is_accepted_and_g90_1_refused() {
    let mut p = Parser::new(Settings::default());
    let mut q = Parser::new(Settings::default());
    let a = p.line(1, "G21 G91 G91.1 G2 X2 I1 F100").unwrap();
    let b = q.line(1, "G21 G91 G2 X2 I1 F100").unwrap();
    assert_eq!(a, b);
    assert_eq!(p.modes(), q.modes());
    let e = p.line(2, "G90.1").unwrap_err();
    assert!(matches!(e.kind, ErrorKind::UnsupportedG(_)), "{e:?}");
    assert!(std::format!("{e}").contains("G90.1"), "{e}");
}
