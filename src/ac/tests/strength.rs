//! Host tests of the cutters' limits from their geometry (host tests): against a hand calculation
//! and as the beam formulas scale.

use crate::ac::strength::{derived, Limits, Strength};
use crate::gcode::tools::ToolKind;

/// The Fig. 1 cutter by hand: d_e = 0.8 x 12.7 = 10.16 mm, d_e^3 = 1048.77 mm^3, L = 2 D =
/// 25.4 mm; F = 1000 x pi x 1048.77 / (32 x 25.4) = 4053.7 N (the paper's example cutter: 4000 N);
/// T = 1000 / sqrt(3) x pi x 1048.77 / 16 = 118 892 N mm = 118.89 N m.
#[test]
fn the_fig1_cutters_limits_match_the_hand_calculation() {
    let l = derived(ToolKind::Flat, 12.7, &Strength::HSS).unwrap();
    assert!((l.force_n - 4053.7).abs() < 0.5, "{l:?}");
    assert!((l.torque_nm - 118.89).abs() < 0.01, "{l:?}");
    // A ball end mill's shank and flutes are the flat one's.
    assert_eq!(derived(ToolKind::Ball, 12.7, &Strength::HSS), Some(l));
}

/// Bending over an overhang in diameters scales as D^2, twist as D^3; a drill out twice as far
/// bends at half the force and twists as an end mill; no diameter, no limits.
#[test]
fn the_limits_scale_as_the_beam_formulas() {
    let s = Strength::HSS;
    let big = derived(ToolKind::Flat, 12.0, &s).unwrap();
    let small = derived(ToolKind::Flat, 3.0, &s).unwrap();
    let r = 3.0f32 / 12.0;
    assert!((small.force_n / big.force_n / (r * r) - 1.0).abs() < 1e-5);
    assert!((small.torque_nm / big.torque_nm / (r * r * r) - 1.0).abs() < 1e-5);
    let drill = derived(ToolKind::Drill, 12.0, &s).unwrap();
    assert!((drill.force_n / big.force_n - 0.5).abs() < 1e-6);
    assert_eq!(drill.torque_nm, big.torque_nm);
    // The allowable stress scales both.
    let weak = Strength {
        allowable_mpa: 500.0,
        ..s
    };
    let w: Limits = derived(ToolKind::Flat, 12.0, &weak).unwrap();
    assert!((w.force_n / big.force_n - 0.5).abs() < 1e-6);
    assert!((w.torque_nm / big.torque_nm - 0.5).abs() < 1e-6);
    for d in [0.0, -3.0, f32::NAN, f32::INFINITY] {
        assert_eq!(derived(ToolKind::Flat, d, &s), None, "{d}");
    }
}

/// A tool's limits: the table's own where it gives them, derived from its geometry where it
/// leaves them 0, none for a tool without a diameter or limits (the machine's settings apply).
#[test]
fn a_tools_limits_are_its_own_or_its_geometrys() {
    use crate::ac::strength::{of_tool, Source};
    use crate::gcode::tools::Tool;
    let s = Strength::HSS;
    let six = Tool {
        diameter_pm: 6_000_000_000,
        flutes: 4,
        kind: ToolKind::Ball,
        ..Tool::default()
    };
    let geo = derived(ToolKind::Ball, 6.0, &s).unwrap();
    assert_eq!(of_tool(&six, &s), Some((geo, Source::Geometry)));
    let own = Tool {
        force_limit_n: 900.0,
        torque_limit_nm: 12.0,
        ..six
    };
    let (l, src) = of_tool(&own, &s).unwrap();
    assert_eq!((l.force_n, l.torque_nm, src), (900.0, 12.0, Source::Table));
    let half = Tool {
        force_limit_n: 900.0,
        ..six
    };
    let (l, src) = of_tool(&half, &s).unwrap();
    assert_eq!(
        (l.force_n, l.torque_nm, src),
        (900.0, geo.torque_nm, Source::Geometry)
    );
    assert_eq!(of_tool(&Tool::default(), &s), None);
}
