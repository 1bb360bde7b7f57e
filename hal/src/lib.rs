//! millac boards (hal/): the board-agnostic AC side of the apps, [`actask`] (the sampler and the
//! AC period over a board's ADC and log; the serial loader is the core's `millac::rt::loader`),
//! and the boards. Each board implements the core's ports (`millac::ports`: step/sign port, frame
//! and pulse timers, sample clock, force/torque ADC) with its registers, and has a thin RTIC app
//! in `src/bin/` that binds the core's ISR and task bodies (`millac::rt`) to its interrupts.
//! Board modules (feature `lm3s6965`, default): `lm3s6965` (the board QEMU emulates) with
//! `simadc`, its lockstep simulated ADC (semihosting FIFOs to the host), `uart` (UART0, a PL011,
//! and the loader's board hooks), `storage`, the settings record in a host file, `results`, the
//! result file the host tools read (the app's log is defmt, see its docs), `session`, the serial
//! mode's log `serve.nc`, and `semihost`, the host-file calls they all use. The Nucleo-F446RE is
//! its own package (hal/nucleo-f446re) over the shared modules: a second device crate here would
//! clash. Init, ISR and task contexts as each item says.
#![no_std]

pub mod actask;

#[cfg(feature = "lm3s6965")]
pub mod lm3s6965;
#[cfg(feature = "lm3s6965")]
pub mod results;
#[cfg(feature = "lm3s6965")]
pub mod semihost;
#[cfg(feature = "lm3s6965")]
pub mod session;
#[cfg(feature = "lm3s6965")]
pub mod simadc;
#[cfg(feature = "lm3s6965")]
pub mod storage;
#[cfg(feature = "lm3s6965")]
pub mod uart;
