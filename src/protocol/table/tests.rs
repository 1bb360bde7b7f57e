//! Host tests of the settings table (`$$` listing, `$N=value` errors and units, BLU change,
//! round trips) and of the persistent record (CRC, bit flips, truncations, a storage double).
extern crate std;
use super::record::{self, LoadStatus, RecordError, RECORD_LEN};
use super::*;
use crate::ac::settings::{Calibration, FeedCeiling, Pick};
use crate::ports::SettingsStorage;
use crate::settings::ACCEL_RANGE;
use proptest::prelude::*;
use std::string::String;
use std::vec::Vec;

const DEFAULT_LIST: &str =
    "$200=0.00254\r\n$0=5\r\n$6=0\r\n$10=1\r\n$13=0\r\n$20=1\r\n$21=1\r\n$22=0\r\n$23=0\r\n$24=25\r\n\
$25=500\r\n$26=250\r\n$27=1\r\n$30=1000\r\n$110=4013.1492\r\n$111=4013.1492\r\n\
$112=4013.1492\r\n$120=635\r\n$121=635\r\n$122=635\r\n$130=254\r\n$131=254\r\n$132=101.6\r\n\
$201=5000\r\n$202=3000\r\n$203=400\r\n$204=100\r\n$205=25\r\n$206=20\r\n$207=5\r\n\
$230=-254\r\n$231=-254\r\n$232=-101.6\r\n$250=1\r\n$251=3\r\n$252=1000\r\n$253=10\r\n$254=4000\r\n\
$255=80\r\n$256=0.9\r\n$257=75000\r\n$258=100\r\n$259=3000\r\n$260=-0.1\r\n$261=0\r\n$262=3\r\n\
$263=0\r\n$264=1500\r\n$265=10\r\n$266=0\r\n$267=4\r\n$268=2\r\n$269=600\r\n$270=0.05\r\n$271=2.5\r\n$272=2.5\r\n$273=2048\r\n$274=2048\r\n$275=2048\r\n$276=1\r\n$277=0\r\n$278=1\r\n$280=20\r\n\
$281=1500\r\n$282=1\r\n$283=50\r\n$284=6.35\r\n$285=0.6\r\n$286=1.4\r\n$287=5\r\n$288=5\r\n\
$341=0\r\n$342=30\r\n$343=25\r\n$344=200\r\n$345=0\r\n$346=0\r\n";

/// The record of the defaults, version 7 (its acceleration 250 000 BLU/s^2 since the ramps came,
/// issue 7; `$30` max spindle speed, `$264` the AC's nominal feed and `$265` the GPC weight appended in version 2, issues
/// 8 and 9; GPC (`$251=3`, `$265=10`) the default feed law since issue 9; version 3 appends the process
/// monitors' `$267` flutes, `$269` spindle speed, `$266` chatter threshold and `$268` breakage (issue 10); version 4
/// appends `$276` the chatter depth step and its payload grows to 204 bytes, version 5 `$277` the chatter spindle speed
/// limit, 208 bytes (issue 10); version 6 appends the work offsets and the tool table (all zero in
/// the defaults), 816 bytes; version 7 inserts the set-up after the AC's settings (`$6`,
/// `$21`-`$27`, `$341`-`$346`: 41 bytes, 857 in all; its fields and the CRC checked here with
/// Python's struct and zlib.crc32): a change of the layout must bump the version.
const DEFAULT_IMAGE: &str = "4d4c535408005a030088130000b80b0000dd660000900100006400000019000000204e000088130000881300006079\
feff6079feffc063ffffa0860100a0860100409c000090d0030090d0030090d003000103e80300000a000000cdcc4c\
3d00000045000020400000004500002040000000450000007a450000a0426666663ff824010064000000b80b0000cd\
ccccbd14000000dc050100320000003333cb409a99193f3333b33f0000a0400500000003000000000100e8030000dc\
05000000002041040000005802000000000000020000803f000000000100010000a861000020a10700fa000000e803\
00000030750000a8610000400d03000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000\
00000000000000000000000000000000000000007da6bbfa";

fn listing(m: &MachineSettings) -> String {
    let mut s = String::new();
    m.list(&mut s).unwrap();
    s
}

fn set(m: &mut MachineSettings, stmt: &str) -> Result<(), SetError> {
    m.set_line(stmt)
}

#[test]
fn defaults_list_in_grbl_units_and_line_by_line() {
    let m = MachineSettings::default();
    assert_eq!(m.validate(&crate::settings::BoardLimits::GENERIC), Ok(()));
    assert_eq!(listing(&m), DEFAULT_LIST);
    let lines: Vec<String> = (0..TABLE.len())
        .map(|i| String::from(m.line(i).unwrap().as_str()))
        .collect();
    assert_eq!(lines.join("\r\n") + "\r\n", DEFAULT_LIST);
    assert!(m.line(TABLE.len()).is_none());
}

#[test]
fn table_lists_the_blu_first_then_ascending_numbers() {
    assert_eq!(TABLE[0].number, 200);
    for w in TABLE[1..].windows(2) {
        assert!(
            w[0].number < w[1].number,
            "${} before ${}",
            w[0].number,
            w[1].number
        );
    }
    for n in [
        0u16, 6, 10, 13, 20, 21, 27, 110, 120, 130, 200, 250, 288, 341, 346,
    ] {
        assert_eq!(entry(n).map(|e| e.number), Some(n));
    }
    for n in [1u16, 2, 3, 4, 5, 11, 12, 28, 100, 133, 299, 340, 347] {
        assert!(entry(n).is_none(), "${n} is not millac's");
    }
}

#[test]
fn grbl_settings_take_grbl_units() {
    let mut m = MachineSettings::default();
    // The set-up's lengths and rates are um and um/min, listed in mm and mm/min whatever the BLU.
    set(&mut m, "$27=2.5").unwrap();
    set(&mut m, "$25=1200.0004").unwrap();
    set(&mut m, "$345=-120.25").unwrap();
    assert_eq!(m.setup.homing_pulloff_um, 2_500);
    assert_eq!(
        m.setup.homing_seek_um_min, 1_200_000,
        "rounded to the um/min"
    );
    assert_eq!(m.setup.setter_um, [-120_250, 0]);
    set(&mut m, "$0=10").unwrap();
    assert_eq!(m.nc.pulse_width_ns, 10_000);
    set(&mut m, "$0=2.5004").unwrap();
    assert_eq!(m.nc.pulse_width_ns, 2_500, "rounded to the ns");
    // 3000 mm/min = 50 mm/s = 19 685.04 BLU/s -> 19 685, listed exactly.
    set(&mut m, "$110=3000").unwrap();
    assert_eq!(m.nc.rapid_hz, 19_685);
    let at = |n: u16| TABLE.iter().position(|e| e.number == n).unwrap();
    assert_eq!(m.line(at(110)).unwrap().as_str(), "$110=2999.994");
    assert_eq!(m.line(at(111)).unwrap().as_str(), "$111=2999.994");
    set(&mut m, "$111=2999.994").unwrap();
    set(&mut m, "$112=3000").unwrap(); // the same rate once rounded
    set(&mut m, "$121=100").unwrap();
    let d = Settings::default().accel_blu_s2[0];
    assert_eq!(m.nc.accel_blu_s2, [d, 39_370, d]);
    set(&mut m, "$130=200").unwrap();
    assert_eq!(m.nc.soft_max[0], 78_740);
    set(&mut m, "$232=-50.8").unwrap();
    assert_eq!(m.nc.soft_min[2], -20_000);
    set(&mut m, "$10=2").unwrap();
    set(&mut m, "$13=1").unwrap();
    set(&mut m, "$20=1").unwrap();
    assert_eq!(
        m.report,
        ReportSettings {
            status_mask: 2,
            inches: true
        }
    );
    set(&mut m, " $206 = 12.5 ").unwrap();
    assert_eq!(m.nc.decel_tau_us, 12_500);
    set(&mut m, "$207=1.25").unwrap();
    assert_eq!(m.nc.sign_setup_ns, 1_250);
}

#[test]
fn ac_settings_take_their_units_and_signs() {
    let mut m = MachineSettings::default();
    for stmt in [
        "$250=0",
        "$261=1",
        "$263=1",
        "$262=8",
        "$253=20",
        "$258=50",
        "$259=2500",
    ] {
        set(&mut m, stmt).unwrap();
    }
    assert!(!m.ac_enabled);
    assert_eq!((m.ac.pick, m.ac.ceiling), (Pick::Latest, FeedCeiling::Frm));
    set(&mut m, "$263=2").unwrap();
    assert_eq!(m.ac.ceiling, FeedCeiling::Plan);
    // A board whose frame leaves the plan ratio out refuses it, and keeps what it had.
    let mut f = MachineSettings::default();
    let (n, v) = parse_assignment("$263=2").unwrap();
    let e = f
        .set(
            n,
            v,
            &crate::settings::BoardLimits {
                plan_ratio: false,
                ..crate::settings::BoardLimits::GENERIC
            },
        )
        .unwrap_err();
    assert_eq!(e, SetError::Invalid(Invalid::PlanNotOnThisBoard));
    assert_eq!(e.code(), 52);
    assert_eq!(f.ac.ceiling, FeedCeiling::Programmed);
    assert!(set(&mut m, "$263=3").is_err());
    assert_eq!(m.ac.ceiling, FeedCeiling::Plan);
    set(&mut m, "$263=1").unwrap();
    assert_eq!((m.ac.peak_windows, m.ac.period_ms), (8, 20));
    assert_eq!((m.ac.f_min, m.ac.f_max), (50, 2500));
    set(&mut m, "$260=-0.2").unwrap();
    set(&mut m, "$270=-0.05").unwrap();
    set(&mut m, "$256=0.95").unwrap();
    set(&mut m, "$284=3.175").unwrap();
    set(&mut m, "$274=2047.5").unwrap();
    assert_eq!(m.ac.overload_e, -0.2f32);
    assert_eq!(
        m.ac.cal[0],
        Calibration {
            gain: -0.05,
            offset: 2048.0
        }
    );
    assert_eq!(m.ac.cal[1].offset, 2047.5);
    assert_eq!(
        (m.ac.optimal_fraction, m.ac.tool_radius_mm),
        (0.95f32, 3.175f32)
    );
    let l = listing(&m);
    for line in [
        "$260=-0.2\r",
        "$270=-0.05\r",
        "$256=0.95\r",
        "$284=3.175\r",
        "$274=2047.5\r",
    ] {
        assert!(l.contains(line), "{line} in {l}");
    }
}

#[test]
fn refused_sets_give_grbl_errors_and_change_nothing() {
    use crate::ac::settings::AcSettingsError as A;
    use crate::settings::SettingsError as N;
    use crate::settings::SetupError as U;
    let r = SetError::Invalid(Invalid::Range);
    let cases: [(&str, SetError); 63] = [
        ("$1=25", SetError::Unsupported),
        ("$2=0", SetError::Unsupported),
        ("$100=250", SetError::Unsupported),
        ("$999=1", SetError::Unsupported),
        ("$0", SetError::Unsupported),
        ("$=5", SetError::Unsupported),
        ("$x=5", SetError::Unsupported),
        ("$123456=5", SetError::Unsupported),
        ("$0=", SetError::BadNumber),
        ("$0=abc", SetError::BadNumber),
        ("$0=1.2.3", SetError::BadNumber),
        ("$0=0.0000000000000000001", SetError::BadNumber),
        ("$202=1.5", SetError::BadNumber),
        ("$0=-5", SetError::Negative),
        ("$201=-1", SetError::Negative),
        ("$130=-1", SetError::Negative),
        ("$254=-4000", SetError::Negative),
        ("$201=50", SetError::Invalid(Invalid::Nc(N::FrameRate))),
        ("$0=1000", SetError::Invalid(Invalid::Nc(N::PulseTiming))),
        ("$120=0.01", SetError::Invalid(Invalid::Nc(N::Acceleration))),
        ("$230=1", SetError::Invalid(Invalid::Nc(N::SoftLimits))),
        ("$254=0", SetError::Invalid(Invalid::Ac(A::Limits))),
        (
            "$256=1.5",
            SetError::Invalid(Invalid::Ac(A::OptimalFraction)),
        ),
        ("$258=5000", SetError::Invalid(Invalid::Ac(A::FeedRange))),
        ("$282=1500", SetError::Invalid(Invalid::Ac(A::FrozenCodes))),
        ("$20=0", r),
        ("$111=1000", r),
        ("$10=4", r),
        ("$13=2", r),
        ("$250=2", r),
        ("$251=4", r),
        ("$265=-1", SetError::Negative),
        ("$265=2000000", SetError::Invalid(Invalid::Ac(A::GpcLambda))),
        ("$264=5000", SetError::Invalid(Invalid::Ac(A::NominalFeed))),
        ("$264=50", SetError::Invalid(Invalid::Ac(A::NominalFeed))),
        ("$266=-1", SetError::Negative),
        ("$266=inf", SetError::BadNumber),
        ("$267=0", SetError::Invalid(Invalid::Ac(A::Monitor))),
        ("$267=9", SetError::Invalid(Invalid::Ac(A::Monitor))),
        ("$268=3", r),
        ("$269=0", SetError::Invalid(Invalid::Ac(A::Monitor))),
        ("$269=100001", SetError::Invalid(Invalid::Ac(A::Monitor))),
        ("$200=0.002", r),
        ("$200=0.0025401", r),
        ("$254=0.0000001", r),
        ("$201=99999999999999999999999", r),
        ("$6=2", r),
        ("$21=2", r),
        ("$22=-1", SetError::Negative),
        ("$23=8", SetError::Invalid(Invalid::Setup(U::Choice))),
        ("$23=1.5", SetError::BadNumber),
        ("$24=0", SetError::Invalid(Invalid::Setup(U::Rate))),
        // The default rapid rate is 4013.149 mm/min.
        ("$25=4014", SetError::Invalid(Invalid::Setup(U::Rate))),
        ("$26=10001", SetError::Invalid(Invalid::Setup(U::Choice))),
        ("$27=0", SetError::Invalid(Invalid::Setup(U::Distance))),
        // Z's travel is 203.2 mm.
        ("$27=203.2", SetError::Invalid(Invalid::Setup(U::Distance))),
        ("$27=-1", SetError::Negative),
        ("$341=3", r),
        ("$342=0", SetError::Invalid(Invalid::Setup(U::Distance))),
        (
            "$342=10000.001",
            SetError::Invalid(Invalid::Setup(U::Distance)),
        ),
        ("$343=0", SetError::Invalid(Invalid::Setup(U::Rate))),
        ("$344=5000", SetError::Invalid(Invalid::Setup(U::Rate))),
        ("$345=3000000", r),
    ];
    let mut m = MachineSettings::default();
    for (stmt, want) in cases {
        assert_eq!(set(&mut m, stmt), Err(want), "{stmt}");
        assert_eq!(m, MachineSettings::default(), "{stmt} changed the settings");
    }
    assert_eq!(SetError::BadNumber.code(), 2);
    assert_eq!(SetError::Unsupported.code(), 3);
    assert_eq!(SetError::Negative.code(), 4);
    assert_eq!(r.code(), 52);
    assert_eq!(SetError::Storage.code(), 7);
    assert_eq!(
        SetError::Invalid(Invalid::Nc(N::FrameRate)).message(),
        N::FrameRate.message()
    );
}

#[test]
fn blu_change_keeps_the_mm_values() {
    let mut m = MachineSettings::default();
    set(&mut m, "$200=0.00254").unwrap();
    assert_eq!(
        m,
        MachineSettings::default(),
        "the same BLU changes nothing"
    );
    set(&mut m, "$200=0.0010").unwrap();
    assert_eq!(m.nc.blu, Blu::Micron);
    assert_eq!(m.nc.soft_max, [254_000, 254_000, 101_600]);
    assert_eq!(m.nc.soft_min, [-254_000, -254_000, -101_600]);
    // The default 25 in/s^2 = 635 mm/s^2 = 635 000 um/s^2.
    assert_eq!(
        m.nc.accel_blu_s2,
        [Settings::default().accel_blu_s2[0] * 254 / 100; 3]
    );
    assert_eq!(m.nc.rapid_hz, 66_886); // 26 333 x 2.54 = 66 885.8
    let l = listing(&m);
    assert!(l.starts_with("$200=0.001\r\n"), "{l}");
    assert!(l.contains("$130=254\r\n$131=254\r\n$132=101.6\r\n"), "{l}");
    assert!(l.contains("$110=4013.16\r\n"), "{l}");
    // Back: limits round inward, rates to the nearest.
    set(&mut m, "$130=100.002").unwrap();
    set(&mut m, "$230=-100.002").unwrap();
    set(&mut m, "$200=0.00254").unwrap();
    // 100.002 mm = 39 370.87 BLU: inward, not to the nearest.
    assert_eq!((m.nc.soft_min[0], m.nc.soft_max[0]), (-39_370, 39_370));
    assert_eq!(m.nc.rapid_hz, 26_333);
    assert_eq!(m.nc.accel_blu_s2, [250_000; 3]);
}

#[test]
fn acceleration_is_validated() {
    let mut s = Settings::default();
    assert_eq!(s.validate(&crate::settings::BoardLimits::GENERIC), Ok(()));
    for (a, ok) in [
        (99, false),
        (100, true),
        (100_000_000, true),
        (100_000_001, false),
        (0, false),
    ] {
        s.accel_blu_s2 = [100_000, a, 100_000];
        assert_eq!(
            s.validate(&crate::settings::BoardLimits::GENERIC).is_ok(),
            ok,
            "{a}"
        );
        assert_eq!(ACCEL_RANGE.contains(&a), ok);
    }
}

fn real(lo: f32, hi: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        lo..=hi,
        (1u32..=100_000).prop_map(move |k| (k as f32 / 1000.0).clamp(lo, hi))
    ]
}

prop_compose! {
    fn arb_nc()(blu in any::<bool>(), frame in 100u32..=100_000, extra in 0u32..=200_000,
                q0 in 1u32..=1_000_000, pw in 1u64..=1000, ss in 0u64..=1000,
                ptp in (1u32..1000, 1u32..1000, 1u32..1000), tau in 1_000u32..=10_000_000,
                smin in prop::array::uniform3(-100_000_000i32..=0),
                smax in prop::array::uniform3(0i32..=100_000_000),
                accel in prop::array::uniform3(ACCEL_RANGE)) -> Settings {
        let rapid = (frame + extra).min(200_000);
        let half = (1_000_000_000 / rapid as u64) * 3 / 4 / 2;
        Settings {
            blu: if blu { Blu::Micron } else { Blu::TenthMil },
            frame_hz: frame,
            q0,
            rapid_hz: rapid,
            ptp_steps: [ptp.0 + ptp.1 + ptp.2, ptp.1 + ptp.2, ptp.2],
            decel_tau_us: tau,
            pulse_width_ns: (half * pw / 1000).max(1) as u32,
            sign_setup_ns: (half * ss / 1000) as u32,
            soft_min: smin,
            soft_max: smax,
            accel_blu_s2: accel,
        }
    }
}

prop_compose! {
    fn arb_ac()(rates in (100u32..=100_000, 0u32..=1000, 1u32..=10_000_000),
                gains in prop::array::uniform3((real(1e-6, 1e4), any::<bool>())),
                offsets in prop::array::uniform3(prop_oneof![Just(0.0f32), real(1e-6, 4095.0)]),
                picks in (any::<bool>(), any::<bool>()),
                limits in (real(1e-6, 1e7), real(1e-6, 1e7), real(1e-6, 1.0), real(1e-6, 1.0)),
                feeds in (1u32..=1_000_000, 1u32..=1_000_000),
                counts in (0u32..=1_000_000, 1u16..=4095, 0u16..=100, 0u32..=1_000_000),
                ft in (real(1e-6, 1000.0), real(1e-6, 100.0), real(1e-6, 100.0), real(1e-6, 1e7)),
                ft_periods in 0u32..=100_000, peak_windows in 1u32..=8,
                law in (0u8..4, 0u32..=1000, prop_oneof![Just(0.0f32), real(1e-6, 1e6)]),
                monitors in (1u32..=8, 1u32..=100_000, prop_oneof![Just(0.0f32), real(1e-6, 1e6)],
                             0u8..=2, prop_oneof![Just(0.0f32), real(1e-6, 50.0)],
                             0u32..=100_000, any::<bool>())) -> AcSettings {
        let (sample_hz, p, fdot_m) = rates;
        let lo = 1000u32.div_ceil(sample_hz).max(1);
        let cal = [0, 1, 2].map(|k| Calibration {
            gain: if gains[k].1 { -gains[k].0 } else { gains[k].0 },
            offset: offsets[k],
        });
        AcSettings {
            sample_hz,
            period_ms: lo + (1000 - lo) * p / 1000,
            cal,
            pick: if picks.0 { Pick::Latest } else { Pick::Peak },
            force_limit_n: limits.0,
            torque_limit_nm: limits.1,
            optimal_fraction: limits.2,
            fdot_m,
            f_min: feeds.0.min(feeds.1),
            f_max: feeds.0.max(feeds.1),
            overload_e: -limits.3,
            stuck_samples: counts.0,
            jump_codes: counts.1,
            frozen_codes: counts.2,
            frozen_samples: counts.3,
            tool_radius_mm: ft.0,
            ft_ratio_min: ft.1.min(ft.2),
            ft_ratio_max: ft.1.max(ft.2),
            ft_floor_nm: ft.3,
            ft_periods,
            peak_windows,
            ceiling: if picks.1 { FeedCeiling::Frm } else { FeedCeiling::Programmed },
            strategy: [AcStrategy::Paper, AcStrategy::Integral, AcStrategy::Mrac, AcStrategy::Gpc]
                [law.0 as usize],
            gpc_lambda: law.2,
            nominal_feed: {
                let (lo, hi) = (feeds.0.min(feeds.1), feeds.0.max(feeds.1));
                lo + ((hi - lo) as u64 * law.1 as u64 / 1000) as u32
            },
            flutes: monitors.0,
            monitor_rpm: monitors.1,
            chatter_threshold: monitors.2,
            breakage: crate::ac::Breakage::from_code(monitors.3).unwrap(),
            chatter_step_mm: monitors.4,
            chatter_max_rpm: monitors.5,
            chatter: monitors.6,
        }
    }
}

prop_compose! {
    /// A set-up whose rates fit the slowest rapid rate `arb_nc` makes (100 BLU/s of 2.54 um:
    /// 15 240 um/min) and whose pull-off fits the shortest travel it makes.
    fn arb_setup()(flags in prop::array::uniform3(any::<bool>()), dir in 0u8..=7,
                   rates in prop::array::uniform4(1u32..=15_000), debounce in 0u32..=10_000,
                   pulloff in 1u32..=100, change in 0u8..=2, distance in 1u32..=10_000_000,
                   setter in prop::array::uniform2(-2_000_000_000i32..=2_000_000_000))
                   -> crate::settings::Setup {
        crate::settings::Setup {
            probe_invert: flags[0],
            hard_limits: flags[1],
            homing: flags[2],
            homing_dir_mask: dir,
            homing_feed_um_min: rates[0],
            homing_seek_um_min: rates[1],
            homing_debounce_ms: debounce,
            homing_pulloff_um: pulloff,
            tool_change: change,
            probe_distance_um: distance,
            probe_slow_um_min: rates[2],
            probe_seek_um_min: rates[3],
            setter_um: setter,
        }
    }
}

prop_compose! {
    fn arb_settings()(nc in arb_nc(), ac in arb_ac(), on in any::<bool>(), mask in 0u8..=3,
                      inches in any::<bool>(), rpm in 1u32..=1_000_000, setup in arb_setup())
                      -> MachineSettings {
        MachineSettings {
            nc,
            ac,
            ac_enabled: on,
            report: ReportSettings { status_mask: mask, inches },
            spindle_max_rpm: rpm,
            setup,
            work: crate::gcode::Work::default(),
        }
    }
}

prop_compose! {
    /// Work offsets and a tool table as the parser can make them (within +-1000 km, diameters not
    /// negative, flutes at most 32, limits listable).
    fn arb_work()(systems in prop::array::uniform6(prop::array::uniform3(-crate::gcode::offsets::MAX_PM..=crate::gcode::offsets::MAX_PM)),
                  homes in prop::array::uniform2(prop::array::uniform3(-1_000_000_000_000i64..=1_000_000_000_000)),
                  tools in prop::collection::vec((-1_000_000_000_000i64..=1_000_000_000_000, 0i64..=100_000_000_000, 0u8..=crate::gcode::tools::MAX_FLUTES, 0u8..3, prop_oneof![Just(0.0f32), 1e-3f32..1e6], prop_oneof![Just(0.0f32), 1e-3f32..1e4]), 16)) -> crate::gcode::Work {
        let mut w = crate::gcode::Work { systems, g28: homes[0], g30: homes[1], ..Default::default() };
        for (n, t) in tools.into_iter().enumerate() {
            w.tools.set(n as u32 + 1, crate::gcode::Tool {
                length_pm: t.0,
                diameter_pm: t.1,
                flutes: t.2,
                kind: [crate::gcode::ToolKind::Flat, crate::gcode::ToolKind::Ball, crate::gcode::ToolKind::Drill][t.3 as usize],
                force_limit_n: t.4,
                torque_limit_nm: t.5,
            });
        }
        w
    }
}

fn lines(m: &MachineSettings) -> Vec<String> {
    listing(m)
        .split("\r\n")
        .filter(|l| !l.is_empty())
        .map(String::from)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, max_global_rejects: 4096, ..ProptestConfig::default() })]

    /// Every `$$` line set back gives exactly the same settings (and is accepted).
    #[test]
    fn listing_sets_back_to_the_same_settings(s in arb_settings()) {
        prop_assume!(s.validate(&crate::settings::BoardLimits::GENERIC).is_ok());
        let mut m = s;
        for l in lines(&s) {
            prop_assert_eq!(m.set_line(&l), Ok(()), "{}", l);
        }
        prop_assert_eq!(m, s);
        prop_assert_eq!(record::encode(&m), record::encode(&s));
    }

    /// A `$$` listing restored onto the defaults (grbl GUIs' restore) gives the same settings; an
    /// order-dependent set refused once (a range that crosses the current one) goes in a second
    /// pass, and the BLU converts the mm settings set before it, set again in the second pass.
    #[test]
    fn listing_restores_onto_the_defaults(s in arb_settings()) {
        prop_assume!(s.validate(&crate::settings::BoardLimits::GENERIC).is_ok());
        let mut m = MachineSettings::default();
        for _ in 0..3 {
            for l in lines(&s) {
                let _ = m.set_line(&l);
            }
        }
        prop_assert_eq!(listing(&m), listing(&s));
        prop_assert_eq!(m, s);
    }

    /// The record round-trips, work offsets and tool table included, and a random bit flip in it
    /// is refused.
    #[test]
    fn record_round_trips_and_flips_are_refused(s in arb_settings(), w in arb_work(), bit in 0usize..RECORD_LEN * 8) {
        let s = MachineSettings { work: w, ..s };
        prop_assume!(s.validate(&crate::settings::BoardLimits::GENERIC).is_ok());
        let img = record::encode(&s);
        prop_assert_eq!(record::decode(&img, &crate::settings::BoardLimits::GENERIC).map(crate::settings::Valid::get), Ok(s));
        let mut bad = img;
        bad[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(record::decode(&bad, &crate::settings::BoardLimits::GENERIC).is_err());
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| std::format!("{x:02x}")).collect()
}

#[test]
fn crc32_matches_the_standard_check_value() {
    assert_eq!(record::crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(record::crc32(b""), 0);
}

#[test]
fn record_of_the_defaults_is_stable() {
    let img = record::encode(&MachineSettings::default());
    assert_eq!(img.len(), RECORD_LEN);
    assert_eq!(hex(&img), DEFAULT_IMAGE);
    assert_eq!(
        record::decode(&img, &crate::settings::BoardLimits::GENERIC)
            .map(crate::settings::Valid::get),
        Ok(MachineSettings::default())
    );
}

#[test]
fn every_single_bit_flip_is_refused() {
    let img = record::encode(&MachineSettings::default());
    for bit in 0..RECORD_LEN * 8 {
        let mut bad = img;
        bad[bit / 8] ^= 1 << (bit % 8);
        let e = record::decode(&bad, &crate::settings::BoardLimits::GENERIC).unwrap_err();
        let want: &[RecordError] = match bit / 8 {
            0..4 => &[RecordError::Magic],
            4..6 => &[RecordError::Checksum],
            6..8 => &[RecordError::Truncated, RecordError::Length],
            _ => &[RecordError::Checksum],
        };
        assert!(want.contains(&e), "bit {bit}: {e:?}");
    }
}

#[test]
fn every_truncation_and_extension_is_refused() {
    let img = record::encode(&MachineSettings::default());
    for n in 0..RECORD_LEN {
        assert_eq!(
            record::decode(&img[..n], &crate::settings::BoardLimits::GENERIC),
            Err(RecordError::Truncated),
            "{n} bytes"
        );
    }
    let mut long = img.to_vec();
    long.push(0);
    assert_eq!(
        record::decode(&long, &crate::settings::BoardLimits::GENERIC),
        Err(RecordError::Length)
    );
}

/// Re-seals an image after an edit (a record with a valid CRC).
fn reseal(img: &mut [u8]) {
    let n = img.len() - 4;
    let c = record::crc32(&img[..n]);
    img[n..].copy_from_slice(&c.to_le_bytes());
}

#[test]
fn a_sealed_record_with_bad_values_is_refused() {
    let bad = MachineSettings {
        nc: Settings {
            frame_hz: 50,
            ..Settings::default()
        },
        ..MachineSettings::default()
    };
    let img = record::encode(&bad);
    assert_eq!(
        record::decode(&img, &crate::settings::BoardLimits::GENERIC),
        Err(RecordError::Invalid(Invalid::Nc(
            crate::settings::SettingsError::FrameRate
        )))
    );
    let nan = MachineSettings {
        ac: AcSettings {
            ft_floor_nm: f32::NAN,
            ..AcSettings::default()
        },
        ..MachineSettings::default()
    };
    assert!(matches!(
        record::decode(
            &record::encode(&nan),
            &crate::settings::BoardLimits::GENERIC
        ),
        Err(RecordError::Invalid(_))
    ));
    let mut img = record::encode(&MachineSettings::default());
    img[8] = 7; // BLU code
    reseal(&mut img);
    assert_eq!(
        record::decode(&img, &crate::settings::BoardLimits::GENERIC),
        Err(RecordError::Value)
    );
    let mut img = record::encode(&MachineSettings::default());
    img[4] = 3; // version 3
    reseal(&mut img);
    assert_eq!(
        record::decode(&img, &crate::settings::BoardLimits::GENERIC),
        Err(RecordError::Version(3))
    );
}

/// A settings storage in memory (the host's test double of flash or EEPROM).
#[derive(Default)]
struct MemStorage {
    image: Option<Vec<u8>>,
    refuse: bool,
    stores: usize,
}

impl SettingsStorage for MemStorage {
    fn load(&mut self, buf: &mut [u8]) -> Option<usize> {
        let img = self.image.as_ref()?;
        let n = img.len().min(buf.len());
        buf[..n].copy_from_slice(&img[..n]);
        Some(img.len())
    }

    fn store(&mut self, image: &[u8]) -> bool {
        if self.refuse {
            return false;
        }
        self.stores += 1;
        self.image = Some(image.to_vec());
        true
    }
}

#[test]
fn load_gives_defaults_with_or_without_an_alarm() {
    let d = MachineSettings::default();
    let mut st = MemStorage::default();
    let l = record::load(&mut st, &crate::settings::BoardLimits::GENERIC).unwrap();
    assert_eq!((l.settings.get(), l.status), (d, LoadStatus::Missing));
    assert!(!l.status.alarm());
    st.image = Some(std::vec![0xFF; RECORD_LEN]);
    assert_eq!(
        record::load(&mut st, &crate::settings::BoardLimits::GENERIC)
            .unwrap()
            .status,
        LoadStatus::Missing,
        "erased flash"
    );
    let img = record::encode(&d).to_vec();
    let refused = [
        (img[..100].to_vec(), RecordError::Truncated),
        (std::vec![], RecordError::Truncated),
        (std::vec![0u8; RECORD_LEN], RecordError::Magic),
        (
            [img.clone(), std::vec![0; 1000]].concat(),
            RecordError::Length,
        ),
    ];
    for (image, e) in refused {
        st.image = Some(image);
        let l = record::load(&mut st, &crate::settings::BoardLimits::GENERIC).unwrap();
        assert_eq!((l.settings.get(), l.status), (d, LoadStatus::Refused(e)));
        assert!(l.status.alarm());
    }
    assert_eq!(st.stores, 0, "load never writes");
}

#[test]
fn persistent_sets_store_and_reload() {
    let mut st = MemStorage::default();
    let mut m = MachineSettings::default()
        .validated(&crate::settings::BoardLimits::GENERIC)
        .unwrap();
    for stmt in ["$0=4", "$200=0.001", "$254=3500", "$13=1"] {
        let (n, v) = parse_assignment(stmt).unwrap();
        record::set_persistent(
            &mut m,
            &mut st,
            n,
            v,
            &crate::settings::BoardLimits::GENERIC,
        )
        .unwrap();
    }
    assert_eq!(st.stores, 4);
    let l = record::load(&mut st, &crate::settings::BoardLimits::GENERIC).unwrap();
    assert_eq!((l.settings, l.status), (m, LoadStatus::Loaded));
    assert_eq!(listing(&l.settings), listing(&m));
    // A refused value stores nothing; a refused store changes nothing.
    let (n, v) = parse_assignment("$201=1").unwrap();
    assert!(record::set_persistent(
        &mut m,
        &mut st,
        n,
        v,
        &crate::settings::BoardLimits::GENERIC
    )
    .is_err());
    assert_eq!(st.stores, 4);
    st.refuse = true;
    let before = (m, st.image.clone());
    let (n, v) = parse_assignment("$0=3").unwrap();
    let e = record::set_persistent(
        &mut m,
        &mut st,
        n,
        v,
        &crate::settings::BoardLimits::GENERIC,
    )
    .unwrap_err();
    assert_eq!((e, e.code()), (SetError::Storage, 7));
    assert_eq!((m, st.image.clone()), before);
    // Invalid settings are never stored: only valid ones can be (`record::store` takes a
    // `Valid`), and these are refused on the way to becoming one.
    let bad = MachineSettings {
        report: ReportSettings {
            status_mask: 9,
            inches: false,
        },
        ..m.get()
    };
    assert_eq!(
        bad.validated(&crate::settings::BoardLimits::GENERIC),
        Err(Invalid::Range)
    );
    assert_eq!(st.stores, 4);
}

/// Sends `line` to a protocol whose `$` table is `table`; the protocol's output.
fn over_the_protocol(table: &mut Persistent<MemStorage>, line: &str) -> String {
    use crate::protocol::{Context, Event, Protocol, RxShared, State};
    let shared = std::boxed::Box::leak(std::boxed::Box::new(RxShared::new()));
    let (mut isr, rx) = shared.split();
    let mut p = Protocol::new(rx, 15);
    for b in line.bytes().chain([b'\n']) {
        isr.push_byte(b);
    }
    let machine = table.settings.nc;
    let mut out = String::new();
    let mut cx = Context {
        table,
        modes: crate::gcode::Parser::new(machine).modes(),
        offsets: Default::default(),
        machine: &machine,
        state: State::Idle,
        frame_cycles: None,
        interlock: None,
    };
    while p.poll(&mut out, &mut cx) != Event::None {}
    out
}

/// The serial loader's table: an accepted `$N=value` is stored before its `ok` and loads back at
/// the next start; a refused value or a refused store changes neither the table nor the record
/// (`error:52`, `error:7`); `$RST=*` stores the defaults; a corrupt record loads as the defaults
/// with the refusal for the alarm.
#[test]
fn the_persistent_table_stores_each_set_before_its_ok() {
    let (mut t, status) =
        Persistent::load(MemStorage::default(), crate::settings::BoardLimits::GENERIC).unwrap();
    assert_eq!(
        (t.settings.get(), status),
        (MachineSettings::default(), LoadStatus::Missing)
    );
    assert_eq!(over_the_protocol(&mut t, "$0=7"), "ok\r\n");
    assert_eq!(t.storage.stores, 1);
    let (back, status) = Persistent::load(
        MemStorage {
            image: t.storage.image.clone(),
            ..MemStorage::default()
        },
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    assert_eq!(status, LoadStatus::Loaded);
    assert_eq!(back.settings.nc.pulse_width_ns, 7000);
    assert_eq!(back.settings, t.settings);
    assert!(over_the_protocol(&mut t, "$$").contains("$0=7\r\n"));
    let before = (t.settings, t.storage.image.clone());
    assert_eq!(over_the_protocol(&mut t, "$201=50"), "error:52\r\n");
    t.storage.refuse = true;
    assert_eq!(over_the_protocol(&mut t, "$0=8"), "error:7\r\n");
    assert_eq!(over_the_protocol(&mut t, "$RST=*"), "error:7\r\n");
    assert_eq!((t.settings, t.storage.image.clone()), before);
    t.storage.refuse = false;
    assert_eq!(over_the_protocol(&mut t, "$RST=x"), "error:3\r\n");
    // Work offsets (a G10's): stored with the settings; `$RST=$` keeps them, `$RST=#` clears
    // them and keeps the settings; each change of them moves the epoch the loader watches.
    let mut w = crate::gcode::Work::default();
    w.systems[1] = [25_400_000_000, 0, -1_000_000_000];
    let epoch = t.work_epoch;
    t.set_work(w).unwrap();
    assert_eq!(t.work_epoch, epoch.wrapping_add(1));
    let stored = record::decode(
        t.storage.image.as_ref().unwrap(),
        &crate::settings::BoardLimits::GENERIC,
    );
    assert_eq!(stored.map(|s| s.work), Ok(w));
    assert_eq!(over_the_protocol(&mut t, "$RST=$"), "ok\r\n");
    assert_eq!(
        (t.settings.work, t.settings.nc),
        (w, MachineSettings::default().nc)
    );
    assert_eq!(over_the_protocol(&mut t, "$RST=#"), "ok\r\n");
    assert_eq!(t.work_epoch, epoch.wrapping_add(2));
    assert_eq!(t.settings.get(), MachineSettings::default());
    let stored = t.storage.image.clone().unwrap();
    assert_eq!(
        record::decode(&stored, &crate::settings::BoardLimits::GENERIC)
            .map(crate::settings::Valid::get),
        Ok(MachineSettings::default())
    );
    // One flipped byte: the defaults, refused for its checksum.
    let mut bad = stored;
    bad[20] ^= 0x01;
    let (t, status) = Persistent::load(
        MemStorage {
            image: Some(bad),
            ..MemStorage::default()
        },
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    assert_eq!(status, LoadStatus::Refused(RecordError::Checksum));
    assert_eq!(t.settings.get(), MachineSettings::default());
}

/// A board with its own limits (a fast one, as the Nucleo-F446RE states): the table validates
/// every set for them, so a frame rate the generic board refuses is taken and stored, and the
/// record loads back only where the board can run it.
#[test]
fn a_board_table_validates_sets_and_loads_for_its_limits() {
    use crate::protocol::table::persistent::Persistent;
    use crate::protocol::SettingsTable;
    use crate::settings::BoardLimits;
    let fast = BoardLimits {
        max_frame_hz: 250_000,
        max_rapid_hz: 250_000,
        frame_work_ns: 1_500,
        pulse_end_ns: 400,
        plan_ratio: true,
    };
    let (mut t, status) = Persistent::load(MemStorage::default(), fast).unwrap();
    assert_eq!(status, LoadStatus::Missing);
    // 2 us pulse, 2 us sign setup, rapid and W0 at 200 kHz (the rapid rate first: W0 <= rapid).
    for stmt in ["$0=2", "$207=2", "$110=30480", "$201=200000"] {
        let (n, v) = parse_assignment(stmt).unwrap();
        assert_eq!(t.set(n, v), Ok(()), "{stmt}");
    }
    assert_eq!(t.settings.nc.frame_hz, 200_000);
    // The generic board refuses W0 = 200 kHz (above its 100 kHz), even with pulse timing it
    // accepts at that rapid rate, and it refuses the board's record.
    let mut generic = MachineSettings::default();
    for stmt in ["$0=1", "$207=1", "$110=30480"] {
        generic.set_line(stmt).unwrap();
    }
    assert!(generic.set_line("$201=200000").is_err());
    let mut st = t.storage;
    assert_eq!(
        record::load(&mut st, &fast).unwrap().status,
        LoadStatus::Loaded,
        "the board loads its record"
    );
    assert!(matches!(
        record::load(&mut st, &crate::settings::BoardLimits::GENERIC)
            .unwrap()
            .status,
        LoadStatus::Refused(RecordError::Invalid(_))
    ));
    // Above the board's own maximum: refused, nothing stored.
    let (mut t, _) = Persistent::load(st, fast).unwrap();
    let stores = t.storage.stores;
    let (n, v) = parse_assignment("$201=260000").unwrap();
    assert!(t.set(n, v).is_err());
    assert_eq!(t.storage.stores, stores);
}

/// Settings validated as a whole give their parts as valid settings with no second check (each
/// part passes its own validation), keep their validity with `$250` changed, and a refused
/// `$N=value` on valid settings leaves them as they were; settings a board cannot run do not
/// become valid for it.
#[test]
fn valid_settings_give_valid_parts_and_stay_valid() {
    use crate::settings::BoardLimits;
    let generic = BoardLimits::GENERIC;
    let mut m = MachineSettings::default().validated(&generic).unwrap();
    for stmt in ["$201=20000", "$268=1", "$266=2.5", "$252=100000"] {
        let (n, v) = parse_assignment(stmt).unwrap();
        m.set(n, v, &generic)
            .unwrap_or_else(|e| panic!("{stmt}: {}", e.message()));
    }
    assert_eq!(m.nc().get(), m.nc);
    assert_eq!(m.nc().validate(&generic), Ok(()));
    assert_eq!(m.ac().get(), m.ac);
    assert_eq!(m.ac().validate(), Ok(()));
    let off = m.with_ac_enabled(false);
    assert!(!off.ac_enabled);
    assert_eq!(off.validate(&generic), Ok(()));
    assert_eq!(
        MachineSettings {
            ac_enabled: true,
            ..off.get()
        },
        m.get()
    );
    let before = m;
    let (n, v) = parse_assignment("$201=50").unwrap();
    assert_eq!(
        m.set(n, v, &generic),
        Err(SetError::Invalid(Invalid::Nc(SettingsError::FrameRate)))
    );
    assert_eq!(m, before);
    let slow = BoardLimits {
        max_frame_hz: 1_000,
        ..generic
    };
    assert_eq!(
        MachineSettings::default().validated(&slow),
        Err(Invalid::Nc(SettingsError::FrameRate))
    );
}
