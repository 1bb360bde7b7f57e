//! The settings sector of the STM32F446RE: sector 7 (128 KiB at 0x0806_0000, outside the program's
//! flash in memory.x) as a `millac::flashstore::FlashSector`, so the settings record lives in the
//! core's wear-levelled slot log (`FlashStore`), the same storage layer (`Persistent`) the QEMU
//! board uses over a host file. Init (load) and the loader task (store, only while the machine is
//! idle or in alarm: the protocol takes `$N=value` and `$RST` only then).
//!
//! Registers (RM0390 section 3): KEYR, SR (BSY, the error flags), CR (PG, SER, SNB, PSIZE, STRT,
//! LOCK), ACR (data cache enable and reset). Programming is 32 bits at a time (PSIZE = x32, valid
//! from 2.7 V, the Nucleo's 3.3 V). While the flash is busy every fetch from it stalls, interrupts
//! included: a word takes ~16 us (a record ~3.4 ms), the sector erase 1-2 s (once every 128 stores).
//! The erase therefore stretches the watchdog to ~8 s around itself and restores it after (and is
//! refused if the stretch did not take). The frame interrupt is paused around every operation
//! (the machine stands): a frame stalled by the flash would show as a frame overrun in the DWT
//! figures and raise ALARM:111.
//!
//! With the `qemu` feature the store is [`RamSector`] instead: QEMU's netduinoplus2 models no
//! flash interface (its registers read 0, stores to the flash are dropped).
use millac::flashstore::FlashSector;

/// The settings sector of this build: sector 7 of the flash.
#[cfg(not(feature = "qemu"))]
pub type Sector = Sector7;
/// The settings sector of this build: RAM (QEMU).
#[cfg(feature = "qemu")]
pub type Sector = RamSector;

/// The settings sector of this build. Init context.
pub fn sector() -> Sector {
    #[cfg(not(feature = "qemu"))]
    return Sector7;
    #[cfg(feature = "qemu")]
    return RamSector;
}

/// Sector 7.
const BASE: usize = 0x0806_0000;
const SECTOR: u32 = 7;
const SIZE: usize = 128 * 1024;

const FLASH: usize = 0x4002_3C00;
const ACR: usize = FLASH;
const KEYR: usize = FLASH + 0x04;
const SR: usize = FLASH + 0x0C;
const CR: usize = FLASH + 0x10;
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
const SR_BSY: u32 = 1 << 16;
/// Operation errors: WRPERR, PGAERR, PGPERR, PGSERR (write 1 to clear), and EOP.
const SR_ERRORS: u32 = 0b1111 << 4;
const SR_CLEAR: u32 = SR_ERRORS | 1;
const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_PSIZE_X32: u32 = 0b10 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
const ACR_DCEN: u32 = 1 << 10;
const ACR_DCRST: u32 = 1 << 12;

fn write(addr: usize, value: u32) {
    // SAFETY: the flash interface registers above (valid aligned 32-bit device registers), or a
    // word of sector 7 while CR.PG is set (a program operation; no Rust data lives there).
    unsafe { core::ptr::write_volatile(addr as *mut u32, value) }
}

fn read(addr: usize) -> u32 {
    // SAFETY: as for `write`; also the words of sector 7 (valid flash, read only through here).
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

/// Sector 7 of the on-chip flash.
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct Sector7;

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl Sector7 {
    fn unlock() {
        if read(CR) & CR_LOCK != 0 {
            write(KEYR, KEY1);
            write(KEYR, KEY2);
        }
        write(SR, SR_CLEAR);
    }

    /// Waits for the operation, locks the interface again and says whether it went without error.
    fn finish() -> bool {
        while read(SR) & SR_BSY != 0 {}
        let ok = read(SR) & SR_ERRORS == 0;
        write(CR, CR_LOCK);
        // The data cache may hold words of the sector from before: reset it.
        let acr = read(ACR);
        write(ACR, acr & !ACR_DCEN);
        write(ACR, (acr & !ACR_DCEN) | ACR_DCRST);
        write(ACR, acr);
        ok
    }
}

impl FlashSector for Sector7 {
    const SIZE: usize = SIZE;

    fn read(&mut self, offset: usize, buf: &mut [u8]) -> bool {
        let Some(end) = offset.checked_add(buf.len()) else {
            return false;
        };
        if end > SIZE {
            return false;
        }
        for (k, b) in buf.iter_mut().enumerate() {
            // SAFETY: BASE + offset + k is inside sector 7 (checked above).
            *b = unsafe { core::ptr::read_volatile((BASE + offset + k) as *const u8) };
        }
        true
    }

    fn erase(&mut self) -> bool {
        use crate::board::F446;
        // Not with the short timeout: the erase would outlast it.
        if !F446::watchdog_stretch(true) {
            F446::watchdog_stretch(false);
            return false;
        }
        F446::frame_pause(true);
        Self::unlock();
        write(CR, CR_PSIZE_X32 | CR_SER | (SECTOR << 3));
        write(CR, CR_PSIZE_X32 | CR_SER | (SECTOR << 3) | CR_STRT);
        let ok = Self::finish();
        F446::frame_pause(false);
        F446::watchdog_stretch(false);
        ok
    }

    fn program(&mut self, offset: usize, words: &[u32]) -> bool {
        let Some(end) = words
            .len()
            .checked_mul(4)
            .and_then(|n| n.checked_add(offset))
        else {
            return false;
        };
        if offset % 4 != 0 || end > SIZE {
            return false;
        }
        crate::board::F446::frame_pause(true);
        Self::unlock();
        write(CR, CR_PSIZE_X32 | CR_PG);
        let mut ok = true;
        for (k, &w) in words.iter().enumerate() {
            write(BASE + offset + 4 * k, w);
            while read(SR) & SR_BSY != 0 {}
            if read(SR) & SR_ERRORS != 0 {
                ok = false;
                break;
            }
        }
        let done = Self::finish();
        crate::board::F446::frame_pause(false);
        done && ok
    }
}

/// Bytes of the RAM store under QEMU: four slots.
#[cfg(feature = "qemu")]
const RAM_SIZE: usize = 4 * millac::flashstore::SLOT_LEN;

/// The RAM store's bytes, erased (0xFF) at reset.
#[cfg(feature = "qemu")]
struct RamBytes(core::cell::UnsafeCell<[u8; RAM_SIZE]>);

// SAFETY: used only by the one `RamSector` (init, then the loader task), never concurrently.
#[cfg(feature = "qemu")]
unsafe impl Sync for RamBytes {}

#[cfg(feature = "qemu")]
static RAM: RamBytes = RamBytes(core::cell::UnsafeCell::new([0xFF; RAM_SIZE]));

/// The settings "sector" under QEMU: 1 KiB of RAM with the flash's rules (erase to 0xFF,
/// programming clears bits), lost at reset (the defaults load).
#[cfg(feature = "qemu")]
pub struct RamSector;

#[cfg(feature = "qemu")]
impl RamSector {
    fn bytes(&mut self) -> &mut [u8; RAM_SIZE] {
        // SAFETY: the only reference to RAM lives as long as this `&mut self` (one RamSector).
        unsafe { &mut *RAM.0.get() }
    }
}

#[cfg(feature = "qemu")]
impl FlashSector for RamSector {
    const SIZE: usize = RAM_SIZE;

    fn read(&mut self, offset: usize, buf: &mut [u8]) -> bool {
        match self.bytes().get(offset..offset.saturating_add(buf.len())) {
            Some(src) => {
                buf.copy_from_slice(src);
                true
            }
            None => false,
        }
    }

    fn erase(&mut self) -> bool {
        self.bytes().fill(0xFF);
        true
    }

    fn program(&mut self, offset: usize, words: &[u32]) -> bool {
        let end = offset.saturating_add(4 * words.len());
        if offset % 4 != 0 || end > RAM_SIZE {
            return false;
        }
        let bytes = self.bytes();
        for (k, w) in words.iter().enumerate() {
            for (b, v) in bytes[offset + 4 * k..][..4].iter_mut().zip(w.to_le_bytes()) {
                *b &= v;
            }
        }
        true
    }
}
