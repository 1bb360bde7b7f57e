//! The table of settings: number, name, unit and how each is read from and written to
//! [`MachineSettings`], in `$$` order. Used by [`super`] (the loader task's `$$` and `$N=value`,
//! init's validation) and the host tests.

use super::{AcStrategy, MachineSettings};
use crate::ac::settings::{FeedCeiling, Pick};
use crate::settings::Blu;

/// How an integer setting is shown: listed value = internal x num / den (exact decimals only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Unit {
    /// As stored (whole numbers only).
    One,
    /// Stored in thousandths of the listed unit (ns as us, us as ms).
    Milli,
    /// Stored in BLU (or BLU/s^2), listed in mm (mm/s^2).
    Mm,
    /// Stored in BLU/s, listed in mm/min.
    MmPerMin,
}

impl Unit {
    pub(super) const fn ratio(self, blu: Blu) -> (i128, i128) {
        let nm = blu.nm() as i128;
        match self {
            Unit::One => (1, 1),
            Unit::Milli => (1, 1000),
            Unit::Mm => (nm, 1_000_000),
            Unit::MmPerMin => (60 * nm, 1_000_000),
        }
    }
}

type Get<T> = fn(&MachineSettings) -> T;
type Set<T> = fn(&mut MachineSettings, T) -> Option<()>;

#[derive(Clone, Copy)]
pub(super) enum Kind {
    Int {
        get: Get<i64>,
        set: Set<i64>,
        unit: Unit,
        signed: bool,
    },
    Real {
        get: Get<f32>,
        set: Set<f32>,
        signed: bool,
    },
    /// `$200`: the BLU in mm, 0.00254 or 0.001.
    Blu,
}

/// One line of the table.
#[derive(Clone, Copy)]
pub struct Entry {
    pub number: u16,
    /// grbl's name, or millac's meaning.
    pub name: &'static str,
    pub unit: &'static str,
    pub(super) kind: Kind,
}

fn choice(v: i64, n: i64) -> Option<u8> {
    if (0..n).contains(&v) {
        Some(v as u8)
    } else {
        None
    }
}

macro_rules! int {
    ($n:expr, $name:expr, $u:expr, $unit:expr, $ty:ty, $signed:expr, $($f:tt)+) => {
        Entry {
            number: $n,
            name: $name,
            unit: $u,
            kind: Kind::Int {
                get: |m| m.$($f)+ as i64,
                set: |m, v| {
                    m.$($f)+ = <$ty>::try_from(v).ok()?;
                    Some(())
                },
                unit: $unit,
                signed: $signed,
            },
        }
    };
}

macro_rules! real {
    ($n:expr, $name:expr, $u:expr, $signed:expr, $($f:tt)+) => {
        Entry {
            number: $n,
            name: $name,
            unit: $u,
            kind: Kind::Real {
                get: |m| m.$($f)+,
                set: |m, v| {
                    m.$($f)+ = v;
                    Some(())
                },
                signed: $signed,
            },
        }
    };
}

macro_rules! flag {
    ($n:expr, $name:expr, $get:expr, $set:expr) => {
        Entry {
            number: $n,
            name: $name,
            unit: "choice",
            kind: Kind::Int {
                get: $get,
                set: $set,
                unit: Unit::One,
                signed: false,
            },
        }
    };
}

/// `$111`, `$112`: millac has one rapid rate; they list `$110` and accept only its value.
macro_rules! mirror {
    ($n:expr, $name:expr) => {
        Entry {
            number: $n,
            name: $name,
            unit: "mm/min",
            kind: Kind::Int {
                get: |m| m.nc.rapid_hz as i64,
                set: |m, v| (v == m.nc.rapid_hz as i64).then_some(()),
                unit: Unit::MmPerMin,
                signed: false,
            },
        }
    };
}

/// Every setting, in the order `$$` lists them. grbl's numbers where the meaning is grbl's,
/// millac's own from `$200` (NC) and `$250` (adaptive control). `$200` (the BLU) comes first: the
/// settings listed in mm are kept in BLU, so a listing restored line by line onto the defaults
/// changes the BLU before it sets them.
pub static TABLE: [Entry; 77] = [
    Entry {
        number: 200,
        name: "BLU",
        unit: "mm",
        kind: Kind::Blu,
    },
    int!(
        0,
        "step pulse time",
        "us",
        Unit::Milli,
        u32,
        false,
        nc.pulse_width_ns
    ),
    flag!(
        6,
        "probe pin invert",
        |m| m.setup.probe_invert as i64,
        |m, v| {
            m.setup.probe_invert = choice(v, 2)? == 1;
            Some(())
        }
    ),
    flag!(
        10,
        "status report mask",
        |m| m.report.status_mask as i64,
        |m, v| {
            m.report.status_mask = choice(v, 4)?;
            Some(())
        }
    ),
    flag!(13, "report inches", |m| m.report.inches as i64, |m, v| {
        m.report.inches = choice(v, 2)? == 1;
        Some(())
    }),
    flag!(20, "soft limits (always on)", |_| 1, |_, v| (v == 1)
        .then_some(())),
    flag!(21, "hard limits", |m| m.setup.hard_limits as i64, |m, v| {
        m.setup.hard_limits = choice(v, 2)? == 1;
        Some(())
    }),
    flag!(22, "homing cycle", |m| m.setup.homing as i64, |m, v| {
        m.setup.homing = choice(v, 2)? == 1;
        Some(())
    }),
    int!(
        23,
        "homing direction invert mask",
        "mask",
        Unit::One,
        u8,
        false,
        setup.homing_dir_mask
    ),
    int!(
        24,
        "homing locate feed",
        "mm/min",
        Unit::Milli,
        u32,
        false,
        setup.homing_feed_um_min
    ),
    int!(
        25,
        "homing search seek",
        "mm/min",
        Unit::Milli,
        u32,
        false,
        setup.homing_seek_um_min
    ),
    int!(
        26,
        "homing switch debounce delay",
        "ms",
        Unit::One,
        u32,
        false,
        setup.homing_debounce_ms
    ),
    int!(
        27,
        "homing switch pull-off distance",
        "mm",
        Unit::Milli,
        u32,
        false,
        setup.homing_pulloff_um
    ),
    int!(
        30,
        "max spindle speed (full PWM duty)",
        "rpm",
        Unit::One,
        u32,
        false,
        spindle_max_rpm
    ),
    int!(
        110,
        "X max rate (rapid, all axes)",
        "mm/min",
        Unit::MmPerMin,
        u32,
        false,
        nc.rapid_hz
    ),
    mirror!(111, "Y max rate (= $110)"),
    mirror!(112, "Z max rate (= $110)"),
    int!(
        120,
        "X acceleration",
        "mm/s^2",
        Unit::Mm,
        u32,
        false,
        nc.accel_blu_s2[0]
    ),
    int!(
        121,
        "Y acceleration",
        "mm/s^2",
        Unit::Mm,
        u32,
        false,
        nc.accel_blu_s2[1]
    ),
    int!(
        122,
        "Z acceleration",
        "mm/s^2",
        Unit::Mm,
        u32,
        false,
        nc.accel_blu_s2[2]
    ),
    int!(
        130,
        "X max travel (+ soft limit)",
        "mm",
        Unit::Mm,
        i32,
        false,
        nc.soft_max[0]
    ),
    int!(
        131,
        "Y max travel (+ soft limit)",
        "mm",
        Unit::Mm,
        i32,
        false,
        nc.soft_max[1]
    ),
    int!(
        132,
        "Z max travel (+ soft limit)",
        "mm",
        Unit::Mm,
        i32,
        false,
        nc.soft_max[2]
    ),
    int!(
        201,
        "frame rate W0",
        "Hz",
        Unit::One,
        u32,
        false,
        nc.frame_hz
    ),
    int!(
        202,
        "feed DDA capacity q0",
        "count",
        Unit::One,
        u32,
        false,
        nc.q0
    ),
    int!(
        203,
        "PTP step 1 (every 2nd frame)",
        "BLU",
        Unit::One,
        u32,
        false,
        nc.ptp_steps[0]
    ),
    int!(
        204,
        "PTP step 2 (every 4th frame)",
        "BLU",
        Unit::One,
        u32,
        false,
        nc.ptp_steps[1]
    ),
    int!(
        205,
        "PTP step 3 (every 8th frame)",
        "BLU",
        Unit::One,
        u32,
        false,
        nc.ptp_steps[2]
    ),
    int!(
        206,
        "deceleration time constant",
        "ms",
        Unit::Milli,
        u32,
        false,
        nc.decel_tau_us
    ),
    int!(
        207,
        "sign setup time",
        "us",
        Unit::Milli,
        u32,
        false,
        nc.sign_setup_ns
    ),
    int!(
        230,
        "X - soft limit",
        "mm",
        Unit::Mm,
        i32,
        true,
        nc.soft_min[0]
    ),
    int!(
        231,
        "Y - soft limit",
        "mm",
        Unit::Mm,
        i32,
        true,
        nc.soft_min[1]
    ),
    int!(
        232,
        "Z - soft limit",
        "mm",
        Unit::Mm,
        i32,
        true,
        nc.soft_min[2]
    ),
    flag!(
        250,
        "adaptive control on",
        |m| m.ac_enabled as i64,
        |m, v| {
            m.ac_enabled = choice(v, 2)? == 1;
            Some(())
        }
    ),
    flag!(
        251,
        "AC strategy (0 paper, 1 integral, 2 MRAC, 3 GPC)",
        |m| match m.ac.strategy {
            AcStrategy::Paper => 0,
            AcStrategy::Integral => 1,
            AcStrategy::Mrac => 2,
            AcStrategy::Gpc => 3,
        },
        |m, v| {
            m.ac.strategy = match choice(v, 4)? {
                0 => AcStrategy::Paper,
                1 => AcStrategy::Integral,
                2 => AcStrategy::Mrac,
                _ => AcStrategy::Gpc,
            };
            Some(())
        }
    ),
    int!(
        252,
        "AC sample rate",
        "Hz",
        Unit::One,
        u32,
        false,
        ac.sample_hz
    ),
    int!(253, "AC period", "ms", Unit::One, u32, false, ac.period_ms),
    real!(254, "permissible force", "N", false, ac.force_limit_n),
    real!(255, "permissible torque", "N*m", false, ac.torque_limit_nm),
    real!(
        256,
        "optimal fraction (F0, T0)",
        "ratio",
        false,
        ac.optimal_fraction
    ),
    int!(
        257,
        "max feed acceleration fdot_m",
        "feed/s",
        Unit::One,
        u32,
        false,
        ac.fdot_m
    ),
    int!(258, "min AC feed", "feed", Unit::One, u32, false, ac.f_min),
    int!(259, "max AC feed", "feed", Unit::One, u32, false, ac.f_max),
    real!(260, "overload limit on E", "E", true, ac.overload_e),
    flag!(
        261,
        "window pick (0 peak, 1 latest)",
        |m| match m.ac.pick {
            Pick::Peak => 0,
            Pick::Latest => 1,
        },
        |m, v| {
            m.ac.pick = if choice(v, 2)? == 0 {
                Pick::Peak
            } else {
                Pick::Latest
            };
            Some(())
        }
    ),
    int!(
        262,
        "peak windows",
        "count",
        Unit::One,
        u32,
        false,
        ac.peak_windows
    ),
    flag!(
        263,
        "feed ceiling (0 programmed, 1 FRM, 2 plan)",
        |m| match m.ac.ceiling {
            FeedCeiling::Programmed => 0,
            FeedCeiling::Frm => 1,
            FeedCeiling::Plan => 2,
        },
        |m, v| {
            m.ac.ceiling = match choice(v, 3)? {
                0 => FeedCeiling::Programmed,
                1 => FeedCeiling::Frm,
                _ => FeedCeiling::Plan,
            };
            Some(())
        }
    ),
    int!(
        264,
        "AC nominal feed (integral, MRAC)",
        "feed",
        Unit::One,
        u32,
        false,
        ac.nominal_feed
    ),
    real!(265, "GPC weight lambda", "1", false, ac.gpc_lambda),
    real!(
        266,
        "chatter threshold (0 automatic)",
        "code",
        false,
        ac.chatter_threshold
    ),
    int!(
        267,
        "tool flutes",
        "teeth",
        Unit::One,
        u32,
        false,
        ac.flutes
    ),
    flag!(
        268,
        "breakage detection (0 off, 1 on, 2 on for each tool the table gives flutes)",
        |m| i64::from(m.ac.breakage.code()),
        |m, v| {
            m.ac.breakage = crate::ac::Breakage::from_code(choice(v, 3)?)?;
            Some(())
        }
    ),
    int!(
        269,
        "monitors' spindle speed until an S",
        "rpm",
        Unit::One,
        u32,
        false,
        ac.monitor_rpm
    ),
    real!(270, "T gain", "N*m/code", true, ac.cal[0].gain),
    real!(271, "Fu gain", "N/code", true, ac.cal[1].gain),
    real!(272, "Fv gain", "N/code", true, ac.cal[2].gain),
    real!(273, "T offset", "code", false, ac.cal[0].offset),
    real!(274, "Fu offset", "code", false, ac.cal[1].offset),
    real!(275, "Fv offset", "code", false, ac.cal[2].offset),
    real!(
        276,
        "chatter depth step (0 hold only)",
        "mm",
        false,
        ac.chatter_step_mm
    ),
    int!(
        277,
        "chatter spindle speed up to (0 off)",
        "rpm",
        Unit::One,
        u32,
        false,
        ac.chatter_max_rpm
    ),
    flag!(
        278,
        "chatter detection (0 off, 1 on)",
        |m| i64::from(m.ac.chatter),
        |m, v| {
            m.ac.chatter = choice(v, 2)? == 1;
            Some(())
        }
    ),
    int!(
        280,
        "stuck samples",
        "samples",
        Unit::One,
        u32,
        false,
        ac.stuck_samples
    ),
    int!(
        281,
        "jump codes",
        "codes",
        Unit::One,
        u16,
        false,
        ac.jump_codes
    ),
    int!(
        282,
        "frozen codes",
        "codes",
        Unit::One,
        u16,
        false,
        ac.frozen_codes
    ),
    int!(
        283,
        "frozen samples",
        "samples",
        Unit::One,
        u32,
        false,
        ac.frozen_samples
    ),
    real!(284, "tool radius R", "mm", false, ac.tool_radius_mm),
    real!(285, "F*R/T band min", "ratio", false, ac.ft_ratio_min),
    real!(286, "F*R/T band max", "ratio", false, ac.ft_ratio_max),
    real!(287, "F*R/T floor", "N*m", false, ac.ft_floor_nm),
    int!(
        288,
        "F*R/T periods",
        "periods",
        Unit::One,
        u32,
        false,
        ac.ft_periods
    ),
    flag!(
        341,
        "tool change mode",
        |m| m.setup.tool_change as i64,
        |m, v| {
            m.setup.tool_change = choice(v, 3)?;
            Some(())
        }
    ),
    int!(
        342,
        "tool setter probing distance",
        "mm",
        Unit::Milli,
        u32,
        false,
        setup.probe_distance_um
    ),
    int!(
        343,
        "tool setter slow feed",
        "mm/min",
        Unit::Milli,
        u32,
        false,
        setup.probe_slow_um_min
    ),
    int!(
        344,
        "tool setter seek feed",
        "mm/min",
        Unit::Milli,
        u32,
        false,
        setup.probe_seek_um_min
    ),
    int!(
        345,
        "tool setter X (machine)",
        "mm",
        Unit::Milli,
        i32,
        true,
        setup.setter_um[0]
    ),
    int!(
        346,
        "tool setter Y (machine)",
        "mm",
        Unit::Milli,
        i32,
        true,
        setup.setter_um[1]
    ),
];

/// The table entry of setting `number`.
pub fn entry(number: u16) -> Option<&'static Entry> {
    TABLE.iter().find(|e| e.number == number)
}
