//! grbl 1.1 error and alarm numbers, and the mapping from millac's reasons to them (loader task,
//! host tests). grbl's numbers are used where one fits; millac's own alarms (adaptive-control
//! holds, receive overflow, a refused settings record) have their own range, 100 and up, clear of
//! grbl's 1..=10 and of the extensions other grbl-compatible firmwares use below 100.
//!
//! | millac reason | grbl error | grbl's meaning |
//! | --- | --- | --- |
//! | `UnexpectedCharacter`, line not UTF-8 | 1 | expected a command letter |
//! | `MissingNumber`, `MalformedNumber`, `TooManyDecimals`, `NumberTooLarge` | 2 | bad number format |
//! | unknown or malformed `$` command | 3 | invalid statement |
//! | `NegativeValue` | 4 | negative value |
//! | `$H` (no homing in millac) | 5 | setting disabled |
//! | `$` command that needs Idle while running | 8 | not idle |
//! | G-code line while alarm-locked or jogging | 9 | G-code locked out |
//! | line longer than [`super::LINE_MAX`] bytes, or damaged by a receive overflow | 11 | line overflow |
//! | `SoftLimit` (G-code and jog; the line is refused before anything moves, no alarm) | 15 | travel exceeded |
//! | `$J=` with a G/M code other than G20/G21/G90/G91, or a word other than X Y Z F N | 16 | invalid jog command |
//! | `UnclosedComment`, `UnsupportedLetter`, `UnsupportedG`, `UnsupportedM`, `StopWithMotion`, `NotInDialect` | 20 | unsupported command |
//! | `ModalConflict` | 21 | modal group violation |
//! | `NoFeed`, `$J=` without F | 22 | feed rate undefined |
//! | `NotInteger` | 23 | command value not an integer |
//! | `AxisCommandConflict` | 24 | axis command conflict |
//! | `RepeatedWord` | 25 | word repeated |
//! | `NoAxisWords`, `$J=` without an axis word | 26 | no axis words |
//! | `DwellNeedsP`, `MissingWord`, `InverseTimeNeedsF` | 28 | value word missing |
//! | `CoordinateSystem` | 29 | unsupported coordinate system |
//! | `G53Motion` | 30 | G53 invalid motion mode |
//! | `AxisWordsUnused` | 31 | axis words exist |
//! | `TargetOverflow`, `MoveTooLong`, `ArcFullCircleRadius`, `ArcZeroRadius`, `ArcEndNotOnCircle`, `ArcEndUnreachable`, `ArcTooLarge` | 33 | invalid target |
//! | `ArcRadiusTooSmall` | 34 | arc radius error |
//! | `ArcNeedsCentre` | 35 | no offsets in plane |
//! | `DwellWithAxes`, `UnusedWord`, `ArcRadiusAndOffsets` | 36 | unused words |
//! | `ToolLengthAxis` | 37 | G43.1 dynamic axis error |
//! | `ToolNumber` | 38 | (grblHAL) illegal tool table entry |
//! | `Cycle`: not XY, in G93 | 20 | unsupported command |
//! | `Cycle`: R below Z | 33 | invalid target |
//! | `Cycle`: L < 1, Q <= 0 | 39 | (grblHAL) value out of range |
//!
//! Alarms (`ALARM:N`): [`alarm`].

use crate::ac::{Alarm, SensorFault};
use crate::gcode::error::CycleError;
use crate::gcode::lines::LineError;
use crate::gcode::tape::TapeError;
use crate::gcode::{ErrorKind, GcodeError};

/// A grbl error number for an `error:N` response.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GrblError(pub u8);

impl GrblError {
    pub const EXPECTED_COMMAND_LETTER: GrblError = GrblError(1);
    pub const BAD_NUMBER_FORMAT: GrblError = GrblError(2);
    pub const INVALID_STATEMENT: GrblError = GrblError(3);
    pub const NEGATIVE_VALUE: GrblError = GrblError(4);
    pub const SETTING_DISABLED: GrblError = GrblError(5);
    pub const IDLE_ERROR: GrblError = GrblError(8);
    pub const GCODE_LOCK: GrblError = GrblError(9);
    pub const OVERFLOW: GrblError = GrblError(11);
    pub const TRAVEL_EXCEEDED: GrblError = GrblError(15);
    pub const INVALID_JOG: GrblError = GrblError(16);
    pub const UNSUPPORTED_COMMAND: GrblError = GrblError(20);
    pub const MODAL_GROUP: GrblError = GrblError(21);
    pub const UNDEFINED_FEED: GrblError = GrblError(22);
    pub const COMMAND_VALUE_NOT_INTEGER: GrblError = GrblError(23);
    pub const AXIS_COMMAND_CONFLICT: GrblError = GrblError(24);
    pub const WORD_REPEATED: GrblError = GrblError(25);
    pub const NO_AXIS_WORDS: GrblError = GrblError(26);
    pub const VALUE_WORD_MISSING: GrblError = GrblError(28);
    pub const UNSUPPORTED_COORD_SYS: GrblError = GrblError(29);
    pub const G53_INVALID_MOTION_MODE: GrblError = GrblError(30);
    pub const AXIS_WORDS_EXIST: GrblError = GrblError(31);
    pub const INVALID_TARGET: GrblError = GrblError(33);
    pub const ARC_RADIUS: GrblError = GrblError(34);
    pub const NO_OFFSETS_IN_PLANE: GrblError = GrblError(35);
    pub const UNUSED_WORDS: GrblError = GrblError(36);
    pub const G43_DYNAMIC_AXIS: GrblError = GrblError(37);
    /// grblHAL's: a T or H beyond the tool table.
    pub const ILLEGAL_TOOL: GrblError = GrblError(38);
    /// grblHAL's: a value out of its range (a cycle's L or Q).
    pub const VALUE_OUT_OF_RANGE: GrblError = GrblError(39);
}

/// The grbl error number of a parser error (the table above).
pub const fn gcode_error(kind: &ErrorKind) -> GrblError {
    use ErrorKind as K;
    match kind {
        K::UnexpectedCharacter(_) => GrblError::EXPECTED_COMMAND_LETTER,
        K::MissingNumber(_) | K::MalformedNumber(_) | K::TooManyDecimals(_) => {
            GrblError::BAD_NUMBER_FORMAT
        }
        K::NumberTooLarge(_) => GrblError::BAD_NUMBER_FORMAT,
        K::NegativeValue(_) => GrblError::NEGATIVE_VALUE,
        K::UnclosedComment
        | K::UnsupportedLetter(_)
        | K::UnsupportedG(_)
        | K::UnsupportedM(_)
        | K::StopWithMotion { .. }
        | K::NotInDialect(_) => GrblError::UNSUPPORTED_COMMAND,
        K::ModalConflict { .. } => GrblError::MODAL_GROUP,
        K::NotInteger(_) => GrblError::COMMAND_VALUE_NOT_INTEGER,
        K::AxisCommandConflict => GrblError::AXIS_COMMAND_CONFLICT,
        K::NoAxisWords { .. } => GrblError::NO_AXIS_WORDS,
        K::MissingWord { .. } | K::InverseTimeNeedsF => GrblError::VALUE_WORD_MISSING,
        K::CoordinateSystem => GrblError::UNSUPPORTED_COORD_SYS,
        K::G53Motion => GrblError::G53_INVALID_MOTION_MODE,
        K::AxisWordsUnused { .. } => GrblError::AXIS_WORDS_EXIST,
        K::ToolLengthAxis => GrblError::G43_DYNAMIC_AXIS,
        K::ToolNumber { .. } => GrblError::ILLEGAL_TOOL,
        K::Cycle(CycleError::NotXy | CycleError::InverseTime) => GrblError::UNSUPPORTED_COMMAND,
        K::Cycle(CycleError::RBelowZ) => GrblError::INVALID_TARGET,
        K::Cycle(CycleError::Repeats | CycleError::Peck) | K::ArcTurns => {
            GrblError::VALUE_OUT_OF_RANGE
        }
        K::NoFeed { .. } => GrblError::UNDEFINED_FEED,
        K::RepeatedWord(_) => GrblError::WORD_REPEATED,
        K::DwellNeedsP => GrblError::VALUE_WORD_MISSING,
        K::SoftLimit { .. } => GrblError::TRAVEL_EXCEEDED,
        K::TargetOverflow { .. }
        | K::MoveTooLong
        | K::ArcFullCircleRadius
        | K::ArcZeroRadius
        | K::ArcEndNotOnCircle { .. }
        | K::ArcEndUnreachable { .. }
        | K::ArcTooLarge
        | K::ProbeTarget => GrblError::INVALID_TARGET,
        K::ArcRadiusTooSmall { .. } => GrblError::ARC_RADIUS,
        K::ArcNeedsCentre { .. } => GrblError::NO_OFFSETS_IN_PLANE,
        K::DwellWithAxes | K::UnusedWord(_) | K::ArcRadiusAndOffsets => GrblError::UNUSED_WORDS,
    }
}

/// The grbl error number of a line refused before parsing.
pub const fn line_error(e: LineError) -> GrblError {
    match e {
        LineError::TooLong => GrblError::OVERFLOW,
        LineError::NotUtf8 => GrblError::EXPECTED_COMMAND_LETTER,
    }
}

impl From<&ErrorKind> for GrblError {
    fn from(k: &ErrorKind) -> Self {
        gcode_error(k)
    }
}

impl From<ErrorKind> for GrblError {
    fn from(k: ErrorKind) -> Self {
        gcode_error(&k)
    }
}

impl From<GcodeError> for GrblError {
    fn from(e: GcodeError) -> Self {
        gcode_error(&e.kind)
    }
}

impl From<LineError> for GrblError {
    fn from(e: LineError) -> Self {
        line_error(e)
    }
}

impl From<TapeError> for GrblError {
    fn from(e: TapeError) -> Self {
        match e {
            TapeError::Line { error, .. } => line_error(error),
            TapeError::Gcode(g) => gcode_error(&g.kind),
        }
    }
}

/// `ALARM:N` numbers. grbl's where they fit; millac's own from 100.
pub mod alarm {
    /// grbl 1: hard limit triggered (position likely lost).
    pub const HARD_LIMIT: u8 = 1;
    /// grbl 2: motion target exceeds machine travel. (millac refuses such lines before anything
    /// moves with `error:15`; the number is for a limit the frame itself would detect.)
    pub const SOFT_LIMIT: u8 = 2;
    /// grbl 3: reset while in motion (position may be lost): the firmware raises it when a soft
    /// reset stops a running block.
    pub const ABORT_CYCLE: u8 = 3;
    /// grbl 4: probe failed: the probe was not as the move expects it when it started (touching
    /// before a G38.2/G38.3, clear before a G38.4/G38.5).
    pub const PROBE_INITIAL: u8 = 4;
    /// grbl 5: probe failed: a G38.2/G38.4 ended without the probe's change.
    pub const PROBE_NO_CONTACT: u8 = 5;
    /// grbl 6: homing failed: the cycle was reset (or the e-stop pressed) before it ended.
    pub const HOMING_RESET: u8 = 6;
    /// grbl 8: homing failed: the pull-off did not open the limit switch.
    pub const HOMING_PULLOFF: u8 = 8;
    /// grbl 9: homing failed: no limit switch within the search distance.
    pub const HOMING_NO_SWITCH: u8 = 9;
    /// grblHAL 11: homing required: homing is enabled (`$22`) and the machine has not been
    /// homed since power-up, or its position was lost (a hard limit, an e-stop or a reset in
    /// motion). Only `$H` clears it.
    pub const HOMING_REQUIRED: u8 = 11;
    /// grblHAL 13: probe protection: the probe touched outside a probing move (a jog or a move
    /// ran the probe into the work or the tool setter). The feed is held; `$X` clears it.
    pub const PROBE_PROTECTION: u8 = 13;
    /// grblHAL 10: the e-stop input is (or was) active; the machine stopped at once. `$X` clears
    /// it only once the e-stop is released.
    pub const ESTOP: u8 = 10;
    /// Adaptive control, overload hold: cutting force or torque above the overload limit.
    pub const AC_OVERLOAD: u8 = 100;
    /// Adaptive control, sensor hold: a code stuck at an ADC rail.
    pub const AC_SENSOR_STUCK: u8 = 101;
    /// Adaptive control, sensor hold: a jump larger than plausible.
    pub const AC_SENSOR_JUMP: u8 = 102;
    /// Adaptive control, sensor hold: a code outside 0..=4095.
    pub const AC_SENSOR_RANGE: u8 = 103;
    /// Adaptive control, sensor hold: a channel frozen while the axes feed.
    pub const AC_SENSOR_FROZEN: u8 = 104;
    /// Adaptive control, sensor hold: no fresh samples in an AC period.
    pub const AC_NO_SAMPLES: u8 = 105;
    /// Adaptive control, sensor hold: force and torque disagree (transducer gain).
    pub const AC_MISMATCH: u8 = 106;
    /// Process monitor, chatter hold: the sound spectrum above its threshold.
    pub const AC_CHATTER: u8 = 107;
    /// Process monitor, tool breakage: the feed held and the spindle stopped; `$X` is refused
    /// until a reset has ended the job (the queue dropped, the spindle left off), as after
    /// grbl's hard limit.
    pub const AC_BREAKAGE: u8 = 108;
    /// The frame ISR took more cycles than the board's stated limit (`BoardLimits::frame_work_ns`,
    /// which the settings validation assumed): the pulse and sign timing the validation promised
    /// may not hold. The feed is held; lower W0 (`$201`) or the rapid rate (`$110`) and restart.
    pub const FRAME_OVERRUN: u8 = 111;
    /// Serial receive overflow: a sender broke the character-counting contract and bytes were
    /// refused ([`super::super::Event::RxOverflow`]); its stream is out of step, reset required.
    pub const RX_OVERFLOW: u8 = 110;
    /// The stored settings record was refused at start-up (truncated, corrupt, another version,
    /// invalid values): the defaults are loaded and G-code is locked until `$X`, so nothing moves
    /// with settings the operator did not choose ([`super::super::Protocol::settings_refused`]).
    /// grbl itself answers a failed EEPROM read with `error:7` and goes on unlocked.
    pub const SETTINGS_DEFAULTS: u8 = 120;
}

/// The `ALARM:N` number of an adaptive-control hold.
pub const fn ac_alarm(a: &Alarm) -> u8 {
    match a {
        Alarm::Overload { .. } => alarm::AC_OVERLOAD,
        Alarm::Sensor(SensorFault::Stuck { .. }) => alarm::AC_SENSOR_STUCK,
        Alarm::Sensor(SensorFault::Jump { .. }) => alarm::AC_SENSOR_JUMP,
        Alarm::Sensor(SensorFault::Range { .. }) => alarm::AC_SENSOR_RANGE,
        Alarm::Sensor(SensorFault::Frozen { .. }) => alarm::AC_SENSOR_FROZEN,
        Alarm::NoSamples => alarm::AC_NO_SAMPLES,
        Alarm::ForceTorqueMismatch { .. } => alarm::AC_MISMATCH,
        Alarm::Chatter { .. } => alarm::AC_CHATTER,
        Alarm::ToolBreakage(_) => alarm::AC_BREAKAGE,
    }
}
