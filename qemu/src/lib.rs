//! millac-qemu library (host): the virtual logic analyser. Runs the firmware under QEMU with a TCG
//! plugin and the `pl061_write` trace, turns the GPIO port B writes into timed pin events, writes and
//! reads VCD files and cross-checks step counts with sigrok's `stepper_motor` decoder.
//!
//! Pins (GPIO port B, PL061 at 0x4000_5000): PB0 X_STEP, PB1 Y_STEP, PB2 Z_STEP, PB3 X_SIGN,
//! PB4 Y_SIGN, PB5 Z_SIGN. Sign high = positive direction; a rising step edge = one BLU.
pub mod acreport;
pub mod acsim;
pub mod analysis;
pub mod capture;
pub mod cosim;
pub mod elf;
pub mod fault;
pub mod firmware;
pub mod plugin;
pub mod runner;
pub mod sigrok;
pub mod tools;
pub mod vcd;
