//! The QEMU firmware's log (host): the firmware logs through defmt (`defmt-semihosting`), so QEMU's
//! stdout is a stream of defmt frames; this module decodes them with the `.defmt` table of the
//! firmware's ELF (as knurling's qemu-run does) into readable lines, `<level>: <message>` (a frame
//! without a level is its message alone). What the tools read is not in this stream: it is the
//! firmware's result file (`crate::lm3s_files::RESULT_FILE`, [`crate::emulator::capture::Capture::result`]).
//!
//! An image without a `.defmt` section (a hand-assembled test image, a firmware that prints text)
//! gives its stdout as text.
use anyhow::{Context, Result};
use defmt_decoder::{DecodeError, Table};

/// The decoder of one firmware's log.
pub struct Log {
    table: Option<Table>,
}

impl Log {
    /// Reads the `.defmt` table of the ELF `elf` (the file's bytes). No table for an ELF without
    /// one, nor for a kernel image that is no ELF at all (QEMU loads raw images too).
    pub fn from_elf(elf: &[u8]) -> Result<Log> {
        if !elf.starts_with(b"\x7fELF") {
            return Ok(Log { table: None });
        }
        let table = Table::parse(elf).context("reading the firmware's defmt table")?;
        Ok(Log { table })
    }

    /// True when the firmware logs with defmt (its ELF has the table).
    pub fn is_defmt(&self) -> bool {
        self.table.is_some()
    }

    /// The log text of `stdout`, one line per frame. Bytes that are no frame of this table (a
    /// malformed frame) give one line that says so; a frame cut off at the end (QEMU killed while
    /// the firmware was writing it) likewise.
    pub fn decode(&self, stdout: &[u8]) -> String {
        let Some(table) = &self.table else {
            return String::from_utf8_lossy(stdout).into_owned();
        };
        let mut out = String::new();
        let mut stream = table.new_stream_decoder();
        stream.received(stdout);
        loop {
            match stream.decode() {
                Ok(frame) => {
                    if let Some(level) = frame.level() {
                        out += level.as_str();
                        out += ": ";
                    }
                    out += &frame.display_message().to_string();
                    out.push('\n');
                }
                Err(DecodeError::Malformed) => {
                    out += "(malformed defmt frame)\n";
                    // Raw frames have no boundary to resynchronise on.
                    if !table.encoding().can_recover() {
                        break;
                    }
                }
                Err(DecodeError::UnexpectedEof) => break,
            }
        }
        // rzCOBS frames end with a zero byte: anything after the last one is a frame cut off.
        if stdout.last().is_some_and(|&b| b != 0) && table.encoding().can_recover() {
            out += "(defmt frame cut off at the end)\n";
        }
        out
    }
}

/// Decodes `stdout` with the table of the ELF file `elf`.
pub fn decode_file(elf: &std::path::Path, stdout: &[u8]) -> Result<String> {
    let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    Ok(Log::from_elf(&bytes)?.decode(stdout))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kernel image that is no ELF (QEMU loads raw images too) has no table: its stdout is text.
    #[test]
    fn an_image_without_a_table_gives_its_stdout_as_text() {
        let log = Log::from_elf(&[0x00, 0x10, 0x00, 0x20]).unwrap();
        assert!(!log.is_defmt());
        assert_eq!(log.decode(b"hello\n"), "hello\n");
    }
}
