//! A board's start (init, before any interrupt is enabled): the settings table loaded from the
//! board's storage, validated once for the board's limits, and the frame timer's
//! reloads and the pulse one-shot's reload they give. Both boards' apps begin here.
use crate::nc::{Frame, FrameConfig};
use crate::ports::{Board, SettingsStorage};
use crate::protocol::table::record::{LoadStatus, RecordError};
use crate::protocol::table::{Invalid, Persistent};
use crate::rt::status::{FrameWriter, Home};
use crate::rt::{clocks_for_ns, FrameTask, Reloads};

/// What a board starts with.
pub struct Start<S> {
    /// The stored record (validated as a whole), or the defaults that replaced a missing or
    /// refused one.
    pub table: Persistent<S>,
    /// Why the stored record was refused (the defaults replace it): serial mode raises
    /// `ALARM:120`, program mode runs nothing.
    pub refused: Option<RecordError>,
    /// The frame timer's reloads (W0 and the rapid rate) and the pulse one-shot's.
    pub reloads: Reloads,
    pub pulse: u32,
}

/// Loads the settings for board `B` from `storage`, validated for it once (the record at its
/// decode, or the defaults that replace it); an error means the board cannot run them (the
/// defaults are outside its limits). Init.
pub fn start<B: Board, S: SettingsStorage>(storage: S) -> Result<Start<S>, Invalid> {
    let (table, status) = Persistent::load(storage, B::LIMITS)?;
    let refused = match status {
        LoadStatus::Refused(e) => Some(e),
        LoadStatus::Loaded | LoadStatus::Missing => None,
    };
    let nc = table.settings.nc();
    Ok(Start {
        reloads: Reloads::for_settings::<B>(&nc),
        pulse: B::reload(clocks_for_ns(B::TIMER_HZ, nc.pulse_width_ns)),
        table,
        refused,
    })
}

impl<S> Start<S> {
    /// The frame task for the settings (`PLAN`: the board's `BoardLimits::plan_ratio`),
    /// publishing through the frame ISR's handle.
    pub fn frame<H: Home, const PLAN: bool>(&self, status: FrameWriter<H>) -> FrameTask<H, PLAN> {
        let nc = &self.table.settings.nc;
        FrameTask::new(
            Frame::new(FrameConfig::from_settings(nc)),
            self.reloads,
            status,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::{BoardLimits, IsrBounds, SettingsError};

    struct Slow;
    impl Board for Slow {
        const TIMER_HZ: u32 = 1_000_000;
        fn reload(clocks: u32) -> u32 {
            clocks - 1
        }
        /// A board slower than the default W0 of 5 kHz.
        const LIMITS: BoardLimits = BoardLimits {
            max_frame_hz: 1_000,
            ..BoardLimits::GENERIC
        };
        const ISR_BOUNDS: Option<IsrBounds> = None;
        const SPINDLE: bool = false;
    }

    struct Fast;
    impl Board for Fast {
        const TIMER_HZ: u32 = 1_000_000;
        fn reload(clocks: u32) -> u32 {
            clocks - 1
        }
        const LIMITS: BoardLimits = BoardLimits::GENERIC;
        const ISR_BOUNDS: Option<IsrBounds> = None;
        const SPINDLE: bool = false;
    }

    struct Empty;
    impl SettingsStorage for Empty {
        fn load(&mut self, _: &mut [u8]) -> Option<usize> {
            None
        }
        fn store(&mut self, _: &[u8]) -> bool {
            false
        }
    }

    /// The defaults on a board that runs them: the board's reloads for W0, the rapid rate and
    /// the pulse width (its clock, its reload rule); on a board that cannot, the error.
    #[test]
    fn a_board_starts_with_its_reloads_or_refuses_settings_it_cannot_run() {
        let s = start::<Fast, _>(Empty).unwrap_or_else(|e| panic!("{}", e.message()));
        let nc = s.table.settings.nc;
        assert!(s.refused.is_none());
        assert_eq!(s.reloads.feed, 1_000_000 / nc.frame_hz - 1);
        assert_eq!(
            s.reloads.rapid,
            (1_000_000 + nc.rapid_hz / 2) / nc.rapid_hz - 1
        );
        assert_eq!(s.pulse, nc.pulse_width_ns.div_ceil(1000) - 1);
        let e = start::<Slow, _>(Empty).err().expect("refused");
        assert_eq!(e, Invalid::Nc(SettingsError::FrameRate));
        assert_eq!(e.message(), SettingsError::FrameRate.message());
    }
}
