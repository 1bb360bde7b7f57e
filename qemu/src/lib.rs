//! millac-qemu library (host): everything the host tool does around the firmware and the core.
//! The simulated cutting process itself is the separate crate `millac-plant` (qemu/plant), which
//! knows nothing of the controller; this crate is the evaluation side that connects the two.
//!
//! - Virtual logic analyser: [`capture`] runs the firmware under QEMU with the TCG plugin
//!   ([`plugin`], handler exits from [`elf`]) and the `pl061_write` trace and turns the GPIO port B
//!   writes into timed pin events; [`vcd`] writes and reads VCD files; [`sigrok`] cross-checks the
//!   step counts with sigrok's `stepper_motor` decoder; [`analysis`] checks a capture against its
//!   program (end points, path deviation, feed).
//! - Running the firmware: [`firmware`] builds it, [`tools`] finds or installs the external tools,
//!   [`runner`] runs a program under QEMU and analyses the capture; [`serve`] runs the firmware
//!   in serial mode behind [`port`], the serial port's one cable; [`interrupt`] turns SIGINT
//!   and SIGTERM into an early end with a report; [`defmtlog`] decodes the
//!   firmware's defmt log (QEMU's stdout), whose results are in a file of their own; [`f446`]
//!   runs the Nucleo-F446RE firmware (its `qemu` build) on QEMU's netduinoplus2 and streams a
//!   program to it over USART2 (pins PC4..PC9, same byte layout as below).
//! - Adaptive control: [`cosim`] is the host side of the lockstep simulated ADC (the plant behind
//!   the firmware's ADC) and the `ac.log` parser; [`acsim`] runs the core's frame and AC
//!   controller natively on the host against the plant; [`fault`] injects sensor faults into the
//!   transducer codes; [`acreport`] compares AC, constant feeds and the plant's oracle (the path
//!   from the NC program) and writes ac.csv and the plot; [`bench`] is the AC benchmark (every
//!   feed law, every benchmark program, both drives, against the bound); [`repro`] reproduces
//!   the papers' feed-law experiments (depth steps, TIIM, the pocket, entry and exit) per
//!   strategy.
//!
//! Pins (GPIO port B, PL061 at 0x4000_5000): PB0 X_STEP, PB1 Y_STEP, PB2 Z_STEP, PB3 X_SIGN,
//! PB4 Y_SIGN, PB5 Z_SIGN. Sign high = positive direction; a rising step edge = one BLU.
pub mod acreport;
pub mod acsim;
pub mod alarmlab;
pub mod analysis;
pub mod bench;
pub mod breaklab;
pub mod capture;
pub mod chatterlab;
pub mod cosim;
pub mod defmtlog;
pub mod elf;
pub mod f446;
pub mod fault;
pub mod firmware;
pub mod interrupt;
pub mod model;
pub mod optimise;
pub mod plot;
pub mod plugin;
pub mod port;
pub mod repro;
pub mod runner;
pub mod serve;
pub mod sigrok;
pub mod tools;
pub mod vcd;
