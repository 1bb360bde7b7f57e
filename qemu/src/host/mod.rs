//! The host simulation (host): the core's frame and AC task run natively against the plant, no
//! QEMU; and the sensor faults injected into the simulated transducer (here and in the emulator's
//! ADC); and LinuxCNC's interpreter rs274 as a reference reading of G-code.
pub mod acsim;
pub mod board;
pub mod fault;
pub mod rs274;
