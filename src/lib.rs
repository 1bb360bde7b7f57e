//! millac core: NC + adaptive control after Tlusty, Koren and McNeil's HP 2100A die-sinking
//! system. no_std, no chip dependencies; host-tested (unit tests here, end-to-end programs in
//! tests/). Modules and the contexts that call them:
//! - [`nc`]: validated blocks and the frame (Initiator, PTP, feed and interpolation DDAs), the
//!   frame ISR's work; `nc::sim` drives it on the host.
//! - [`gcode`]: G-code lines -> validated blocks, the loader task's work (the firmware's idle loop
//!   and the host tool's pre-check share the tape).
//! - [`ac`]: the adaptive control (DRR, ECR, FRC, holds and alarms), the sampler's and AC task's
//!   work.
//! - [`monitor`]: tool breakage detection (average force per tooth period, two adaptive
//!   time-series filters), the AC/monitoring task's work every sample and every tooth period.
//! - [`flashstore`]: the settings record's wear-levelled log in a flash sector (init loads, loader
//!   task stores) for the real boards.
//! - [`ports`]: one trait per hardware role, with its context; boards (hal/) and the host
//!   simulation implement them.
//! - [`rt`]: the run-time bodies over the ports (frame ISR, pulse-end ISR, sampler, AC period), the
//!   status words between the contexts and the timer arithmetic of init.
//! - [`wire`]: the formats between the QEMU firmware and the host tool (lockstep ADC, `ac.log`).
//! - [`protocol`]: the grbl 1.1 serial protocol (RX interrupt: realtime bytes and the receive
//!   ring; loader task: lines, `ok` / `error:N`, `$` commands, status reports).
//! - [`inputs`]: debouncing of the operator's inputs, the feed hold / cycle start edges and the
//!   e-stop / limit alarm latch (board's periodic input task, loader task).
//! - [`settings`]: the machine settings and their validation (init, loader, host).
//! - [`protocol`]: the operator's line protocol (loader task); `protocol::table` is the `$$`
//!   table and the persistent settings record (init loads it).
#![cfg_attr(not(test), no_std)]
#[cfg(all(feature = "std", not(test)))]
extern crate std;

pub mod ac;
pub mod flashstore;
pub mod gcode;
pub mod inputs;
pub mod monitor;
pub mod nc;
pub mod ports;
pub mod protocol;
pub mod rt;
pub mod settings;
pub mod wire;

pub use settings::{Blu, Settings, SettingsError, Valid};
