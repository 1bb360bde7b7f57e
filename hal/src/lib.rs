//! millac boards (hal/): each board implements the core's ports (`millac::ports`: step/sign port,
//! frame and pulse timers, sample clock, force/torque ADC) with its registers, and has a thin RTIC
//! app in `src/bin/` that binds the core's ISR and task bodies (`millac::rt`) to its interrupts.
//! Board modules: [`lm3s6965`] (the board QEMU emulates) with [`simadc`], its lockstep simulated
//! ADC (semihosting FIFOs to the host), [`actask`], the AC side of the QEMU app (sampler and AC
//! period), [`uart`] (UART0, a PL011), [`serial`], the loader in serial mode, [`storage`], the
//! settings record in a host file, [`session`], the serial mode's log `serve.nc`, and
//! [`semihost`], the host-file calls they all use. Init, ISR and
//! task contexts as each item says.
#![no_std]

pub mod actask;
pub mod lm3s6965;
pub mod semihost;
pub mod serial;
pub mod session;
pub mod simadc;
pub mod storage;
pub mod uart;
