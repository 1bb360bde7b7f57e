//! millac-qemu library (host): everything the host tool does around the firmware and the core,
//! in four folders by concern. The simulated cutting process itself is the separate crate
//! `millac-plant` (qemu/plant), which knows nothing of the controller; this crate is the
//! evaluation side that connects the two.
//!
//! - [`emulator`]: the firmware under QEMU. [`emulator::firmware`] builds it,
//!   [`emulator::tools`] finds or installs the external tools, [`emulator::capture`] runs it with
//!   the TCG plugin ([`emulator::plugin`], handler exits from [`emulator::elf`]) and turns the
//!   GPIO writes into timed pin events (the virtual logic analyser), [`emulator::runner`] runs a
//!   program and analyses the capture, [`emulator::serve`] runs the firmware in serial mode behind
//!   [`emulator::port`] (the serial port's one cable), [`emulator::cosim`] is the host side of the
//!   lockstep simulated ADC and the `ac.log` parser, [`emulator::defmtlog`] decodes the firmware's
//!   defmt log, [`emulator::f446`] runs the Nucleo-F446RE firmware on QEMU's netduinoplus2.
//! - [`host`]: the simulation without QEMU. [`host::acsim`] runs the core's frame and AC
//!   controller natively against the plant; [`host::fault`] injects sensor faults into the
//!   transducer codes (for both the host and the emulator's ADC); [`host::rs274`] runs LinuxCNC's
//!   interpreter rs274 as a reference reading of G-code (qemu/tests/rs274.rs compares millac's).
//! - [`analysis`]: checks of a capture against its program (end points, path deviation, feed),
//!   [`analysis::vcd`] writes and reads VCD files, [`analysis::sigrok`] cross-checks the step
//!   counts with sigrok's `stepper_motor` decoder.
//! - [`evaluation`]: reports, benchmarks and reproductions: [`evaluation::acreport`] (AC against
//!   constant feeds and the bound, ac.csv and the plot), [`evaluation::bench`] (every feed law,
//!   every program, both drives), [`evaluation::repro`] (the papers' experiments),
//!   [`evaluation::optimise`] and [`evaluation::model`] (offline optimisation and the
//!   model-based method), the labs of the monitors ([`evaluation::alarmlab`],
//!   [`evaluation::breaklab`], [`evaluation::chatterlab`]) and [`evaluation::plot`].
//! - [`interrupt`] turns SIGINT and SIGTERM into an early end with a report (any long run);
//!   [`progress`] shows a long run's progress on a terminal.
//!
//! Pins (GPIO port B, PL061 at 0x4000_5000): PB0 X_STEP, PB1 Y_STEP, PB2 Z_STEP, PB3 X_SIGN,
//! PB4 Y_SIGN, PB5 Z_SIGN. Sign high = positive direction; a rising step edge = one BLU.
pub mod analysis;
pub mod emulator;
pub mod evaluation;
/// What the Nucleo-F446RE is (its clocks, limits and ISR bounds, `millac::ports::Board`): the
/// board's own file, for the CI's checks of its build and the budget benchmark (one definition,
/// in the board's folder).
#[path = "../../hal/nucleo-f446re/src/facts.rs"]
pub mod f446_facts;
pub mod host;
pub mod interrupt;
/// What the LM3S6965 under QEMU is (its timer clock, limits, spindle, `millac::ports::Board`):
/// the board's own file, for the host simulation's frame timer (one definition, in the board's
/// folder).
#[path = "../../hal/lm3s6965/src/facts.rs"]
pub mod lm3s_facts;
/// The files the LM3S6965 firmware shares with the host through semihosting: the board's own
/// file (one definition, in the board's folder).
#[path = "../../hal/lm3s6965/src/files.rs"]
pub mod lm3s_files;
pub mod progress;
