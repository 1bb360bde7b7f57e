//! Firmware ELF inspection for the logic analyser (host): finds a function symbol (e.g. an interrupt
//! handler such as `TIMER_0A`), its address and size, and the addresses of its Thumb return
//! instructions, which the QEMU plugin uses as handler exit points.
//!
//! The scanner decodes linearly from the symbol start, so data embedded in the code (literal pools)
//! may add spurious exit addresses (harmless: never executed) and a handler that leaves through a tail
//! call (`b.w other`) has its real return elsewhere; such a handler needs its exits given by hand.
use anyhow::{bail, Context, Result};
use object::{Object, ObjectSection, ObjectSymbol, SymbolKind};
use std::path::Path;

/// A function found in the ELF.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FunctionInfo {
    /// Symbol name as found.
    pub name: String,
    /// Address of the first instruction (Thumb bit cleared).
    pub addr: u32,
    /// Symbol size in bytes.
    pub size: u32,
    /// Addresses of the return instructions found by [`scan_returns`].
    pub returns: Vec<u32>,
    /// Calls and traps in the function (see [`scan_calls_and_traps`]).
    pub calls_and_traps: Vec<u32>,
}

/// Reads `elf` and looks up the function `name`; see [`find_function_in`].
pub fn find_function(elf: &Path, name: &str) -> Result<FunctionInfo> {
    let data = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    find_function_in(&data, name).with_context(|| format!("in {}", elf.display()))
}

/// Looks up the function symbol `name` (exact match) in ELF bytes and scans its code for returns.
pub fn find_function_in(data: &[u8], name: &str) -> Result<FunctionInfo> {
    let file = object::File::parse(data).context("parsing ELF")?;
    let sym = file
        .symbols()
        .find(|s| s.name() == Ok(name) && s.kind() == SymbolKind::Text)
        .with_context(|| format!("function symbol `{name}` not found"))?;
    let addr = (sym.address() & !1) as u32;
    let size = sym.size() as u32;
    if size == 0 {
        bail!("symbol `{name}` has size 0");
    }
    let section_index = sym
        .section_index()
        .with_context(|| format!("symbol `{name}` has no section"))?;
    let section = file.section_by_index(section_index)?;
    let bytes = section.data()?;
    let start = (u64::from(addr))
        .checked_sub(section.address())
        .context("symbol before its section")? as usize;
    let code = bytes
        .get(start..start + size as usize)
        .with_context(|| format!("symbol `{name}` extends past its section"))?;
    Ok(FunctionInfo {
        name: name.to_string(),
        addr,
        size,
        returns: scan_returns(code, addr),
        calls_and_traps: scan_calls_and_traps(code, addr),
    })
}

/// Addresses of the instructions in `code` that call out or trap: BL, BLX (immediate or register),
/// UDF (16- and 32-bit), BKPT and SVC. A handler without any has no panic path: a Rust panic on
/// Cortex-M is a call to the panic machinery or a UDF trap.
pub fn scan_calls_and_traps(code: &[u8], base: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut i = 0usize;
    let half = |i: usize| code.get(i..i + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    while let Some(h) = half(i) {
        if is_thumb32(h) {
            if let Some(h2) = half(i + 2) {
                let bl = h & 0xF800 == 0xF000 && (h2 & 0xD000 == 0xD000 || h2 & 0xD001 == 0xC000);
                let udf_w = h & 0xFFF0 == 0xF7F0 && h2 & 0xF000 == 0xA000;
                if bl || udf_w {
                    out.push(base + i as u32);
                }
            }
            i += 4;
        } else {
            let blx_reg = h & 0xFF87 == 0x4780;
            let udf = h & 0xFF00 == 0xDE00;
            let bkpt = h & 0xFF00 == 0xBE00;
            let svc = h & 0xFF00 == 0xDF00;
            if blx_reg || udf || bkpt || svc {
                out.push(base + i as u32);
            }
            i += 2;
        }
    }
    out
}

/// True when a Thumb halfword is the first half of a 32-bit instruction.
pub fn is_thumb32(first: u16) -> bool {
    matches!(first >> 11, 0b11101..=0b11111)
}

/// Scans little-endian Thumb-2 code placed at `base` and returns the addresses of return
/// instructions: `bx lr` (0x4770), `pop {.., pc}` (0xBDxx), `ldmia.w sp!, {.., pc}` / `pop.w`
/// (0xE8BD, next halfword bit 15 set) and `ldr.w pc, [sp], #4` (0xF85D 0xFB04).
pub fn scan_returns(code: &[u8], base: u32) -> Vec<u32> {
    let half =
        |i: usize| -> Option<u16> { code.get(i..i + 2).map(|b| u16::from_le_bytes([b[0], b[1]])) };
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(h) = half(i) {
        if is_thumb32(h) {
            let Some(h2) = half(i + 2) else { break };
            let ret = (h == 0xE8BD && h2 & 0x8000 != 0) || (h == 0xF85D && h2 == 0xFB04);
            if ret {
                out.push(base + i as u32);
            }
            i += 4;
        } else {
            if h == 0x4770 || h & 0xFF00 == 0xBD00 {
                out.push(base + i as u32);
            }
            i += 2;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes(halves: &[u16]) -> Vec<u8> {
        halves.iter().flat_map(|h| h.to_le_bytes()).collect()
    }

    #[test]
    fn finds_calls_and_traps() {
        // bl <x> (f000 f800); b.w <x> (f000 b800, not a call); blx r3 (4798); bx lr (4770, a return);
        // udf #0 (de00); udf.w (f7f0 a000); bkpt (be00); svc 0xab (dfab); movs r0, #1 (2001)
        let code = bytes(&[
            0xF000, 0xF800, 0xF000, 0xB800, 0x4798, 0x4770, 0xDE00, 0xF7F0, 0xA000, 0xBE00, 0xDFAB,
            0x2001,
        ]);
        assert_eq!(
            scan_calls_and_traps(&code, 0x300),
            vec![0x300, 0x308, 0x30C, 0x30E, 0x312, 0x314]
        );
    }

    #[test]
    fn finds_16_bit_returns() {
        // push {r7, lr}; mov r7, sp; pop {r7, pc}; bx lr
        let code = bytes(&[0xB580, 0x466F, 0xBD80, 0x4770]);
        assert_eq!(scan_returns(&code, 0x100), vec![0x104, 0x106]);
    }

    #[test]
    fn finds_32_bit_returns() {
        // movw r0, #..; pop.w {r4-r11, pc}; ldr.w pc, [sp], #4; ldmia.w sp!, {r4, lr} (not a return)
        let code = bytes(&[
            0xF240, 0x0000, 0xE8BD, 0x8FF0, 0xF85D, 0xFB04, 0xE8BD, 0x4010,
        ]);
        assert_eq!(scan_returns(&code, 0x200), vec![0x204, 0x208]);
    }

    #[test]
    fn does_not_match_inside_32_bit_instructions() {
        // 0x4770 and 0xBD00 as the second halves of 32-bit instructions must not be reported.
        let code = bytes(&[0xF240, 0x4770, 0xF000, 0xBD00, 0x4770]);
        assert_eq!(scan_returns(&code, 0), vec![8]);
    }

    #[test]
    fn truncated_tail_is_ignored() {
        let code = bytes(&[0x4770, 0xE8BD]);
        assert_eq!(scan_returns(&code, 0), vec![0]);
        let mut odd = bytes(&[0x4770]);
        odd.push(0xBD);
        assert_eq!(scan_returns(&odd, 0), vec![0]);
    }

    #[test]
    fn thumb32_rule() {
        assert!(is_thumb32(0xE8BD));
        assert!(is_thumb32(0xF85D));
        assert!(is_thumb32(0xF000));
        assert!(!is_thumb32(0xE7FE)); // b . (16-bit)
        assert!(!is_thumb32(0xBD80));
    }
}

/// What a firmware image takes of the chip: flash (everything loaded from flash: code, read-only
/// data and the initial values of `.data`) and static RAM (`.data`, `.bss`, `.uninit`: what the
/// stack does not get).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryUse {
    pub flash: u64,
    pub ram: u64,
}

/// Sums the allocated sections of ELF bytes by where they live: a section at or above
/// `ram_origin` is RAM (and, if it has file contents, also flash: its initial values are copied
/// from there at reset); one below is flash. Non-allocated sections (debug info, defmt's symbol
/// table) take no space on the chip.
pub fn memory_use_in(data: &[u8], ram_origin: u64) -> Result<MemoryUse> {
    use object::{SectionFlags, SectionKind};
    let file = object::File::parse(data).context("parsing ELF")?;
    let mut m = MemoryUse { flash: 0, ram: 0 };
    for s in file.sections() {
        let alloc = match s.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc || s.size() == 0 {
            continue;
        }
        let in_file = !matches!(
            s.kind(),
            SectionKind::UninitializedData | SectionKind::UninitializedTls
        ) && s.file_range().is_some();
        if s.address() >= ram_origin {
            m.ram += s.size();
            if in_file {
                m.flash += s.size();
            }
        } else {
            m.flash += s.size();
        }
    }
    Ok(m)
}
