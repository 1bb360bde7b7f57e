//! Host tests of `$T`: listing, setting some fields, every refusal, and the round trip of a
//! listed line (proptest).
extern crate std;
use super::*;
use crate::gcode::tools::MAX_TOOLS;
use crate::protocol::table::MachineSettings;
use crate::protocol::SettingsTable;
use proptest::prelude::*;
use std::string::String;

/// `$T<cmd>` on the settings' table as the protocol calls it (compacted as the protocol does:
/// no spaces or comments, upper case).
fn t(m: &mut MachineSettings, cmd: &str) -> (Result<(), u8>, String) {
    let compact = crate::protocol::compact(cmd);
    let mut out = String::new();
    let r = m.tool(&compact, &mut out);
    (r, out)
}

#[test]
fn a_set_changes_the_named_fields_and_the_listing_shows_them() {
    let mut m = MachineSettings::default();
    assert_eq!(
        t(&mut m, "3=L45.2 D6 N4 K1 F900 M12.5"),
        (Ok(()), String::new())
    );
    let tool = *m.work.tools.get(3).unwrap();
    assert_eq!(
        tool,
        Tool {
            length_pm: 45_200_000_000,
            diameter_pm: 6_000_000_000,
            flutes: 4,
            kind: ToolKind::Ball,
            force_limit_n: 900.0,
            torque_limit_nm: 12.5,
        }
    );
    // Words not given keep their values; any order, lower case, spaces.
    assert_eq!(t(&mut m, "3=k2 l-0.0005").0, Ok(()));
    let after = *m.work.tools.get(3).unwrap();
    assert_eq!(after.kind, ToolKind::Drill);
    assert_eq!(after.length_pm, -500_000);
    assert_eq!((after.diameter_pm, after.flutes), (6_000_000_000, 4));
    assert_eq!(
        t(&mut m, "3"),
        (
            Ok(()),
            "$T3=L-0.0005 D6 N4 K2 F900 M12.5 (drill)\r\n".into()
        )
    );
    // `$T` lists every tool, the empty ones too.
    let (r, all) = t(&mut m, "");
    assert_eq!(r, Ok(()));
    assert_eq!(all.lines().count(), MAX_TOOLS);
    assert!(
        all.starts_with("$T1=L0 D0 N0 K0 F0 M0 (flat end mill)\r\n$T2="),
        "{all}"
    );
    assert!(
        all.contains("\r\n$T3=L-0.0005 D6 N4 K2 F900 M12.5 (drill)\r\n"),
        "{all}"
    );
}

#[test]
fn bad_lines_are_refused_with_their_grbl_error_and_change_nothing() {
    let mut m = MachineSettings::default();
    assert_eq!(t(&mut m, "2=L10 D4 N2").0, Ok(()));
    let before = m;
    for (cmd, code) in [
        ("0=L1", 38),
        ("17=L1", 38),
        ("99999999999=L1", 38),
        ("2=", 3),
        ("=L1", 3),
        ("X=L1", 3),
        ("2=Q1", 3),
        ("2=L1 L2", 3),
        ("2=L", 2),
        ("2=L1.2.3", 2),
        ("2=N2.5", 2),
        ("2=D-1", 4),
        ("2=F-1", 4),
        ("2=M-0.5", 4),
        ("2=N-1", 4),
        ("2=N33", 52),
        ("2=N300", 52),
        ("2=K3", 52),
        ("2=F1e3", 3),
        ("2=F0.0000001", 52),
        ("2=F1000000000000000", 52),
        ("2=L1000000000.000000001", 52),
        ("2=D1000000001", 52),
        // A good word before a bad one: still nothing changes.
        ("2=L1 D-1", 4),
    ] {
        assert_eq!(t(&mut m, cmd).0, Err(code), "$T{cmd}");
        assert_eq!(m, before, "$T{cmd} changed the table");
    }
}

proptest! {
    /// Any tool a record may hold, listed by `$T<n>` and set back on an empty table, is the same
    /// tool: the listing is exact.
    #[test]
    fn a_listed_tool_set_back_is_the_same_tool(
        n in 1u32..=MAX_TOOLS as u32,
        length_pm in -crate::gcode::offsets::MAX_PM..=crate::gcode::offsets::MAX_PM,
        diameter_pm in 0..=crate::gcode::offsets::MAX_PM,
        flutes in 0..=MAX_FLUTES,
        kind in 0u8..3,
        force in prop_oneof![Just(0.0f32), 1e-6f32..1e12],
        torque in prop_oneof![Just(0.0f32), 1e-6f32..1e12],
    ) {
        let tool = Tool {
            length_pm,
            diameter_pm,
            flutes,
            kind: ToolKind::from_code(kind).unwrap(),
            force_limit_n: force,
            torque_limit_nm: torque,
        };
        let mut m = MachineSettings::default();
        m.work.tools.set(n, tool);
        prop_assert!(m.work.valid());
        let (r, line) = t(&mut m, &std::format!("{n}"));
        prop_assert_eq!(r, Ok(()));
        let set = line.trim_end().strip_prefix("$T").unwrap();
        let mut fresh = MachineSettings::default();
        prop_assert_eq!(t(&mut fresh, set).0, Ok(()), "{}", line);
        prop_assert_eq!(fresh.work.tools.get(n), Some(&tool), "{}", line);
    }
}
