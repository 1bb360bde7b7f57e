//! The firmware under QEMU (host): building it, running it with the virtual logic analyser,
//! serving its serial port, the simulated ADC's host side, its defmt log.
pub mod capture;
pub mod cosim;
pub mod defmtlog;
pub mod elf;
pub mod f446;
pub mod firmware;
pub mod plugin;
pub mod port;
pub mod runner;
pub mod serve;
pub mod tools;
