//! The files the QEMU board's firmware shares with the host tools through semihosting, by name
//! (init, the loader, the sampler and AC tasks; the host tools include this file too,
//! `millac_qemu::lm3s_files`): the formats in them are the core's (`millac::wire`); where they
//! live is this board's fact. The firmware opens the `*_FILE` names, the host the `*_NAME`s.
#![allow(dead_code)]

/// Request FIFO (firmware -> host). The names are NUL-terminated for the firmware's semihosting
/// open; the host takes them without the NUL (`*_NAME`).
pub const REQ_FILE: &str = "adc.req\0";
/// Response FIFO (host -> firmware).
pub const RESP_FILE: &str = "adc.resp\0";
/// The AC log the firmware writes in the run directory.
pub const AC_LOG_FILE: &str = "ac.log\0";
/// The persistent settings record (`millac::protocol::table::record`) in QEMU's working
/// directory: init loads it, the serial loader stores it after every accepted `$N=value`. The host
/// (`serve --settings FILE`) links it to the operator's file.
pub const SETTINGS_FILE: &str = "settings.bin\0";
/// The session log of the serial mode (`millac::wire::SessionLine`s).
pub const SERVE_LOG_FILE: &str = "serve.nc\0";
/// The firmware's results for the host tools (`millac::wire`, "Result file").
pub const RESULT_FILE: &str = "result.txt\0";
/// The machine model's limit switches (`millac::inputs::LimitSwitches`' file form), read once
/// when serial mode starts; none: no switches (`$H` then fails with `ALARM:9`).
pub const MACHINE_FILE: &str = "machine.txt\0";
/// The names without their NUL.
pub const REQ_NAME: &str = strip_nul(REQ_FILE);
pub const RESP_NAME: &str = strip_nul(RESP_FILE);
pub const AC_LOG_NAME: &str = strip_nul(AC_LOG_FILE);
pub const SETTINGS_NAME: &str = strip_nul(SETTINGS_FILE);
pub const SERVE_LOG_NAME: &str = strip_nul(SERVE_LOG_FILE);
pub const RESULT_NAME: &str = strip_nul(RESULT_FILE);
pub const MACHINE_NAME: &str = strip_nul(MACHINE_FILE);

/// `s` without a trailing NUL.
const fn strip_nul(s: &str) -> &str {
    match s.as_bytes().split_last() {
        Some((0, rest)) => match core::str::from_utf8(rest) {
            Ok(t) => t,
            Err(_) => s,
        },
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The host's names are the firmware's without the NUL.
    #[test]
    fn the_names_are_the_files_without_their_nul() {
        assert_eq!(REQ_NAME, "adc.req");
        assert_eq!(RESP_NAME, "adc.resp");
        assert_eq!(AC_LOG_NAME, "ac.log");
        assert_eq!(SETTINGS_NAME, "settings.bin");
        assert_eq!(SERVE_LOG_NAME, "serve.nc");
        assert_eq!(RESULT_NAME, "result.txt");
        assert_eq!(MACHINE_NAME, "machine.txt");
    }
}
