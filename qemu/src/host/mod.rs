//! The host simulation (host): the core's frame and AC task run natively against the plant, no
//! QEMU; and the sensor faults injected into the simulated transducer (here and in the emulator's
//! ADC).
pub mod acsim;
pub mod board;
pub mod fault;
