//! A wear-levelled [`SettingsStorage`] in one flash sector: a log of fixed-size slots, appended
//! one per store, the sector erased only when every slot is used. Init loads (the newest committed
//! slot), the loader task stores (after every accepted `$N=value` and `$RST=`, which the protocol
//! takes only in Idle or Alarm); host tests with a RAM sector that enforces the flash rules
//! (`flashstore/tests.rs`).
//!
//! Meant for the STM32F446RE's last sector (sector 7, 128 KiB at 0x0806_0000): 128 slots of
//! [`SLOT_LEN`] bytes (1 KiB: the settings record with the work offsets and the tool table is 869
//! bytes), so a sector erase (~1-2 s, reads stall meanwhile) comes once every 128 stores, and
//! 10 000 erase cycles last 1.28 million stores (a store per `$N=value`, `$RST=`, G10 or
//! G28.1/G30.1). A store programs `(8 + n) / 4` rounded up words plus two (the 828-byte record:
//! 211 words, ~3.4 ms at ~16 us a word).
//!
//! Slot layout (little-endian words, as a Cortex-M stores them), slot `k` at sector offset
//! `k * SLOT_LEN`:
//!
//! | offset | bytes | content | programmed |
//! | --- | --- | --- | --- |
//! | 0 | 4 | slot magic `MLSL` ([`SLOT_MAGIC`]) | 1st |
//! | 4 | 2 | image length n, at most [`MAX_IMAGE`] | 1st |
//! | 6 | 2 | slot format ([`SLOT_FORMAT`]) | 1st |
//! | 8 | n | the image; the bytes after it up to the next word are 0xFF | 1st |
//! | 8 + n .. [`CRC_AT`] | | erased (never programmed) | |
//! | [`CRC_AT`] = 1016 | 4 | CRC-32 ([`crc32`], as the record's) of bytes 0 .. 8 + n | 2nd |
//! | [`COMMIT_AT`] = 1020 | 4 | commit word [`COMMIT`] (`DONE`) | 3rd, last |
//!
//! The rules:
//! - A slot is *erased* when all its bytes are 0xFF, *committed* when its commit word is
//!   [`COMMIT`], its magic, format and length are right and its CRC matches; anything else
//!   (a store cut by a power loss, garbage) is skipped: never loaded, never programmed over.
//! - [`SettingsStorage::load`] gives the committed slot with the highest index (slots are used in
//!   order, so that is the newest), or None when there is none.
//! - [`SettingsStorage::store`] writes the first erased slot after the last slot that is not
//!   erased (the scan of `load`, kept in RAM), in three programs: header and image, CRC, commit
//!   word. A power loss before the commit word is complete leaves a slot that is not committed,
//!   so the previous one still loads. Each word is programmed once between erases. The slot is
//!   read back and compared before `store` says true.
//! - When no erased slot is left, `store` erases the sector and writes slot 0. A power loss between
//!   the erase and the commit of slot 0 loses the stored settings: the sector is then erased, `load`
//!   gives None, and `record::load` reports [`LoadStatus::Missing`] (defaults, and no alarm: erased
//!   flash looks like a new board). The window is the erase plus ~4 ms, once every 128 stores;
//!   closing it needs a second sector (copy the newest slot there before erasing), 128 KiB more on
//!   the F446, which we do not spend. An erase cut by a power loss leaves the sector undefined; a
//!   slot that survives it whole is loaded, and may be older than the last store.
//! - Images longer than [`MAX_IMAGE`] are refused (`store` gives false, nothing is written).
//!
//! The board's part: the erase stalls every fetch from flash (the F446 has one bank), so the frame,
//! pulse and sampler ISRs stall with it for 1-2 s; the protocol stores only in Idle or Alarm, when
//! no axis moves, and a watchdog must allow for it. `load` reads up to the whole sector (one
//! 1 KiB slot at a time, from the end); `store` needs ~3 KiB of stack.
//!
//! [`LoadStatus::Missing`]: crate::protocol::table::record::LoadStatus::Missing

use crate::ports::SettingsStorage;
use crate::protocol::table::record::{crc32, RECORD_LEN};

/// Bytes in a slot.
pub const SLOT_LEN: usize = 1024;
/// The first word of every slot.
pub const SLOT_MAGIC: [u8; 4] = *b"MLSL";
/// The slot format (offset 6); any change of the layout bumps it.
pub const SLOT_FORMAT: u16 = 2;
/// Bytes before the image: magic, length, format.
pub const SLOT_HEADER_LEN: usize = 8;
/// Offset of the slot's CRC-32 in the slot.
pub const CRC_AT: usize = SLOT_LEN - 8;
/// Offset of the commit word in the slot.
pub const COMMIT_AT: usize = SLOT_LEN - 4;
/// The commit word, programmed last: `DONE` in memory.
pub const COMMIT: u32 = u32::from_le_bytes(*b"DONE");
/// The longest image a slot holds.
pub const MAX_IMAGE: usize = CRC_AT - SLOT_HEADER_LEN;
/// An erased word.
pub const ERASED: u32 = u32::MAX;

const _: () = assert!(
    RECORD_LEN <= MAX_IMAGE,
    "the settings record must fit a slot"
);
const WORDS: usize = SLOT_LEN / 4;

/// One erasable flash sector, as the store uses it. The board implements it over the flash
/// controller (unlock, 32-bit parallelism, wait for BSY, check the error flags); the host tests
/// over RAM. Offsets are from the start of the sector. Loader task (and init, reads only).
pub trait FlashSector {
    /// Bytes in the sector. The store uses `SIZE / SLOT_LEN` slots; a remainder is unused.
    const SIZE: usize;
    /// Reads `buf.len()` bytes at `offset`; false when the range is outside the sector or the
    /// read failed (the store then treats the bytes as garbage).
    fn read(&mut self, offset: usize, buf: &mut [u8]) -> bool;
    /// Erases the whole sector (every byte 0xFF); false when the controller reported an error.
    fn erase(&mut self) -> bool;
    /// Programs `words` at `offset` (a multiple of 4), in order: word `i` goes to
    /// `offset + 4 i` as its little-endian bytes. Programming only clears bits; the store only
    /// programs erased words, each once between erases. False when the controller reported an
    /// error (some words may be programmed).
    fn program(&mut self, offset: usize, words: &[u32]) -> bool;
}

/// A sector borrowed (the host tests keep the sector to cut its power and look at it).
impl<T: FlashSector> FlashSector for &mut T {
    const SIZE: usize = T::SIZE;
    fn read(&mut self, offset: usize, buf: &mut [u8]) -> bool {
        (**self).read(offset, buf)
    }
    fn erase(&mut self) -> bool {
        (**self).erase()
    }
    fn program(&mut self, offset: usize, words: &[u32]) -> bool {
        (**self).program(offset, words)
    }
}

type SlotBytes = [u8; SLOT_LEN];

/// What a slot holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    Erased,
    Committed {
        len: usize,
    },
    /// Cut by a power loss, garbage, or unreadable: skipped.
    Other,
}

/// The little-endian word at `at` (erased when out of the slot).
fn word_at(bytes: &SlotBytes, at: usize) -> u32 {
    match bytes.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => ERASED,
    }
}

fn put(slot: &mut SlotBytes, at: usize, bytes: &[u8]) {
    for (d, &v) in slot.iter_mut().skip(at).zip(bytes) {
        *d = v;
    }
}

fn classify(bytes: &SlotBytes) -> Slot {
    if bytes.iter().all(|&b| b == 0xFF) {
        return Slot::Erased;
    }
    if word_at(bytes, COMMIT_AT) != COMMIT {
        return Slot::Other;
    }
    let head = word_at(bytes, 4);
    let len = (head & 0xFFFF) as usize;
    let committed = bytes.get(..4) == Some(&SLOT_MAGIC[..])
        && (head >> 16) as u16 == SLOT_FORMAT
        && len <= MAX_IMAGE
        && bytes.get(..SLOT_HEADER_LEN + len).map(crc32) == Some(word_at(bytes, CRC_AT));
    if committed {
        Slot::Committed { len }
    } else {
        Slot::Other
    }
}

/// The slot of `image` as it will read once stored; None when it does not fit.
fn encode(image: &[u8]) -> Option<SlotBytes> {
    if image.len() > MAX_IMAGE {
        return None;
    }
    let mut s = [0xFF; SLOT_LEN];
    let head = image.len() as u32 | (SLOT_FORMAT as u32) << 16;
    put(&mut s, 0, &SLOT_MAGIC);
    put(&mut s, 4, &head.to_le_bytes());
    put(&mut s, SLOT_HEADER_LEN, image);
    let crc = crc32(s.get(..SLOT_HEADER_LEN + image.len())?);
    put(&mut s, CRC_AT, &crc.to_le_bytes());
    put(&mut s, COMMIT_AT, &COMMIT.to_le_bytes());
    Some(s)
}

/// What a scan of the sector found.
struct Scan {
    /// The newest committed slot's bytes and image length.
    newest: Option<(SlotBytes, usize)>,
    /// The slot after the last one that is not erased (0 for an erased sector; `SLOTS` when the
    /// last slot is used).
    next: usize,
}

/// The settings record's storage in a flash sector (see the module doc).
pub struct FlashStore<F: FlashSector> {
    sector: F,
    /// Where the next store looks for an erased slot, once a scan or a store found it; None
    /// before the first scan and after a failed erase.
    next: Option<usize>,
}

impl<F: FlashSector> FlashStore<F> {
    /// Slots in the sector.
    pub const SLOTS: usize = F::SIZE / SLOT_LEN;

    /// The store over `sector`; reads nothing yet (the first load or store scans the sector).
    pub const fn new(sector: F) -> Self {
        FlashStore { sector, next: None }
    }

    /// The sector back.
    pub fn into_inner(self) -> F {
        self.sector
    }

    fn read_slot(&mut self, k: usize) -> Option<SlotBytes> {
        let mut s = [0u8; SLOT_LEN];
        self.sector.read(k * SLOT_LEN, &mut s).then_some(s)
    }

    fn is_erased(&mut self, k: usize) -> bool {
        self.read_slot(k)
            .is_some_and(|s| s.iter().all(|&b| b == 0xFF))
    }

    fn first_erased(&mut self, from: usize) -> Option<usize> {
        (from..Self::SLOTS).find(|&k| self.is_erased(k))
    }

    /// Reads the slots from the last one down to the newest committed slot, and keeps where the
    /// next store goes.
    fn scan(&mut self) -> Scan {
        let mut next = None;
        let mut newest = None;
        for k in (0..Self::SLOTS).rev() {
            let Some(bytes) = self.read_slot(k) else {
                next.get_or_insert(k + 1);
                continue;
            };
            match classify(&bytes) {
                Slot::Erased => {}
                Slot::Other => {
                    next.get_or_insert(k + 1);
                }
                Slot::Committed { len } => {
                    next.get_or_insert(k + 1);
                    newest = Some((bytes, len));
                    break;
                }
            }
        }
        let next = next.unwrap_or(0);
        self.next = Some(next);
        Scan { newest, next }
    }
}

impl<F: FlashSector> SettingsStorage for FlashStore<F> {
    /// The newest committed slot's image, copied into `buf` as far as it fits; its length (more
    /// than `buf.len()` when it did not fit, which the record's length check refuses), or None
    /// when no slot is committed. Init.
    fn load(&mut self, buf: &mut [u8]) -> Option<usize> {
        let (bytes, len) = self.scan().newest?;
        let image = bytes.get(SLOT_HEADER_LEN..SLOT_HEADER_LEN + len)?;
        for (d, &v) in buf.iter_mut().zip(image) {
            *d = v;
        }
        Some(len)
    }

    /// Appends `image` in the next erased slot (erasing the sector when none is left), commits it
    /// and reads it back; false when it is longer than [`MAX_IMAGE`], the flash reported an error
    /// or the read-back differs. Loader task.
    fn store(&mut self, image: &[u8]) -> bool {
        let Some(slot) = encode(image) else {
            return false;
        };
        let from = match self.next {
            Some(k) => k,
            None => self.scan().next,
        };
        let k = match self.first_erased(from) {
            Some(k) => k,
            None => {
                self.next = None;
                if !self.sector.erase() {
                    return false;
                }
                match self.first_erased(0) {
                    Some(k) => k,
                    None => return false,
                }
            }
        };
        // Whatever happens now, slot k is not erased any more.
        self.next = Some(k + 1);
        let mut words = [ERASED; WORDS];
        for (i, w) in words.iter_mut().enumerate() {
            *w = word_at(&slot, 4 * i);
        }
        let body = (SLOT_HEADER_LEN + image.len()).div_ceil(4);
        let base = k * SLOT_LEN;
        let programmed = self.sector.program(base, words.get(..body).unwrap_or(&[]))
            && self
                .sector
                .program(base + CRC_AT, &[word_at(&slot, CRC_AT)])
            && self.sector.program(base + COMMIT_AT, &[COMMIT]);
        programmed && self.read_slot(k) == Some(slot)
    }
}

#[cfg(test)]
mod tests;
