//! End-to-end properties of the program tape (host): a refused line changes nothing and every block
//! accepted before it runs; G91 increments end where one move of their sum would; the line ends
//! (CR, LF, CRLF) and the chunking of the bytes do not change a single pulse.
mod common;

use common::*;
use millac::gcode::{Parsed, Parser};
use millac::Settings;
use proptest::prelude::*;

/// Lines the parser or the line splitter must refuse, whatever modes and position are in force.
const BAD: [&str; 8] = [
    "G1 X999",      // soft limit in mm or inch (or no feed yet)
    "G2 X0.5 Y0.5", // arc without a centre (or no feed yet)
    "G4",           // dwell without P
    "F-1",          // negative feed
    "M2 X1",        // end with motion
    "G1 X1 X2",     // word given twice
    "G0 X1 P2",     // P without a dwell
    "LONG",         // a line too long for the tape (built below)
];

/// Modal words in front of the refused core: they must not take effect either.
const MODAL: [&str; 7] = ["", "G21 ", "G20 ", "G91 ", "G90 ", "G18 ", "F7 "];

fn bad_line(core: usize, modal: usize) -> String {
    let core = if BAD[core] == "LONG" {
        format!("G1 X0 ({})", "x".repeat(300))
    } else {
        BAD[core].to_string()
    };
    format!("{}{}", MODAL[modal], core)
}

/// The results of `lines` through one parser, numbered from `first`; errors are kept in place.
fn parse_all(p: &mut Parser, lines: &[String], first: u32) -> Vec<Result<Parsed, u32>> {
    lines
        .iter()
        .enumerate()
        .map(|(i, l)| p.line(first + i as u32, l).map_err(|e| e.line))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// A refused line: the tape emits every block of the lines before it (and nothing after), they
    /// run to the position those lines program; and the parser, fed on past it, reads the lines
    /// after it exactly as if it had never been there.
    #[test]
    fn a_refused_line_changes_nothing_and_the_blocks_before_it_run(
        moves in proptest::collection::vec(raw_move(), 1..10),
        split in any::<prop::sample::Index>(),
        core in 0..BAD.len(),
        modal in 0..MODAL.len(),
    ) {
        let k = split.index(moves.len() + 1);
        let mut b = Builder::default();
        for m in &moves[..k] {
            b.push(m);
        }
        let before = b.prog.clone();
        for m in &moves[k..] {
            b.push(m);
        }
        let after: Vec<String> = b.prog.lines[before.lines.len()..].to_vec();
        let bad = bad_line(core, modal);

        let mut text = before.text("\n");
        text.push_str(&bad);
        text.push('\n');
        text.push_str(&after.join("\n"));
        let (blocks, err) = tape(&text, 17);
        let bad_no = before.lines.len() as u32 + 1;
        prop_assert_eq!(err.map(|e| e.line()), Some(bad_no), "refused: {}", bad);
        let (alone, err) = tape(&before.text("\n"), 17);
        prop_assert_eq!(err, None);
        prop_assert_eq!(&blocks, &alone, "the blocks before the refused line, all of them");
        let traces = traces(&run(&blocks), blocks.len());
        prop_assert_eq!(traces.last().map_or([0; 3], Trace::end), before.end());

        if bad.len() <= millac::gcode::lines::LINE_MAX {
            let mut with = Parser::new(Settings::default());
            let mut without = Parser::new(Settings::default());
            parse_all(&mut with, &before.lines, 1);
            parse_all(&mut without, &before.lines, 1);
            prop_assert!(with.line(bad_no, &bad).is_err());
            prop_assert_eq!(with.position(), without.position());
            prop_assert_eq!(
                parse_all(&mut with, &after, bad_no + 1),
                parse_all(&mut without, &after, bad_no + 1)
            );
        }
    }

    /// G91: a run of increments (many below a BLU) ends exactly where one incremental move of
    /// their sum ends, and where the exact sum rounds to, in inch or mm.
    #[test]
    fn g91_increments_end_where_one_move_of_their_sum_would(
        mm in any::<bool>(),
        incs in proptest::collection::vec([-300i64..=300, -300i64..=300, -100i64..=100], 1..40),
        rapid in any::<bool>(),
    ) {
        let (unit, dec, units) = if mm { (NM_PER_MM_UNIT, 3, "G21") } else { (NM_PER_INCH_UNIT, 4, "G20") };
        let mv = if rapid { "G0" } else { "G1" };
        let xyz = |d: [i64; 3]| format!("X{} Y{} Z{}", word(d[0], dec), word(d[1], dec), word(d[2], dec));
        let mut steps = format!("{units} G91 F20\n");
        let mut sum = [0i64; 3];
        for d in &incs {
            steps.push_str(&format!("{mv} {}\n", xyz(*d)));
            for k in 0..3 {
                sum[k] += d[k];
            }
        }
        let one = format!("{units} G91 F20\n{mv} {}\n", xyz(sum));
        let end = |text: &str| {
            let (blocks, err) = tape(text, 64);
            assert_eq!(err, None, "{text}");
            traces(&run(&blocks), blocks.len()).last().map_or([0; 3], Trace::end)
        };
        let want = blu(sum.map(|v| v * unit));
        prop_assert_eq!(end(&one), want);
        prop_assert_eq!(end(&steps), want);
    }

    /// CR, LF and CRLF line ends, and any chunking of the bytes, give the same blocks (line numbers
    /// included) and the same pulses frame by frame.
    #[test]
    fn line_ends_and_chunks_give_the_same_pulses(
        p in programs(6),
        chunks in [1usize..300, 1usize..300, 1usize..300],
    ) {
        let (reference, err) = tape(&p.text("\n"), 4096);
        prop_assert_eq!(err, None);
        let pulses = run(&reference);
        for (eol, chunk) in ["\n", "\r", "\r\n"].iter().zip(chunks) {
            let (blocks, err) = tape(&p.text(eol), chunk);
            prop_assert_eq!(err, None);
            // Same blocks with the same line numbers (a CRLF is one line end, not two).
            prop_assert_eq!(&blocks, &reference, "{:?} in chunks of {}", eol, chunk);
            prop_assert!(run(&blocks) == pulses, "{:?} in chunks of {}", eol, chunk);
        }
    }
}
