//! millac core: the NC program (frame ISR), the G-code parser (loader task) and settings, after
//! Tlusty, Koren and McNeil's HP 2100A die-sinking system. no_std, no chip dependencies; host-tested.
#![cfg_attr(not(test), no_std)]

pub mod ac;
pub mod gcode;
pub mod nc;
pub mod ports;
pub mod rt;
pub mod settings;
pub mod wire;

pub use settings::{Blu, Settings, SettingsError};
