//! Host tests of the flash store over a RAM sector that keeps the flash rules: programming only
//! clears bits, and (stricter) only erased words may be programmed, once each between erases; a
//! power loss can be set to stop programming after k words, half-programming the word in progress.
//! An erase is never cut (an erase cut by a power loss leaves the sector undefined: module doc).
extern crate std;

use std::vec;
use std::vec::Vec;

use proptest::prelude::*;

use super::*;
use crate::protocol::table::record::LoadStatus;
use crate::protocol::table::{parse_assignment, MachineSettings, Persistent};
use crate::protocol::SettingsTable;

/// The F446's sector 7.
const SECTOR7: usize = 128 * 1024;
/// A sector of 4 slots, to wrap often.
const SMALL: usize = 4 * SLOT_LEN;
/// The bits a word in progress keeps at 1 when the power goes (a half-programmed word).
const HALF: u32 = 0xF0F0_F0F0;

/// A flash sector in RAM.
#[derive(Clone)]
struct Ram<const N: usize> {
    mem: Vec<u8>,
    erases: usize,
    /// Words programmed whole.
    words: usize,
    /// Words that may still be programmed before the power goes (None: no power loss).
    power: Option<usize>,
    /// No power (or a controller that refuses): program and erase fail.
    dead: bool,
}

impl<const N: usize> Ram<N> {
    fn filled(byte: u8) -> Self {
        Ram {
            mem: vec![byte; N],
            erases: 0,
            words: 0,
            power: None,
            dead: false,
        }
    }

    fn erased() -> Self {
        Self::filled(0xFF)
    }

    /// Power back on.
    fn restart(&mut self) {
        self.power = None;
        self.dead = false;
    }

    fn word(&self, at: usize) -> u32 {
        u32::from_le_bytes(self.mem[at..at + 4].try_into().unwrap())
    }

    fn slot(&self, k: usize) -> &[u8] {
        &self.mem[k * SLOT_LEN..(k + 1) * SLOT_LEN]
    }

    /// Bytes that got there some other way (garbage, an older firmware, a cut store).
    fn poke(&mut self, at: usize, bytes: &[u8]) {
        self.mem[at..at + bytes.len()].copy_from_slice(bytes);
    }
}

impl<const N: usize> FlashSector for Ram<N> {
    const SIZE: usize = N;

    fn read(&mut self, offset: usize, buf: &mut [u8]) -> bool {
        match self.mem.get(offset..offset + buf.len()) {
            Some(s) => {
                buf.copy_from_slice(s);
                true
            }
            None => false,
        }
    }

    fn erase(&mut self) -> bool {
        if self.dead {
            return false;
        }
        self.mem.fill(0xFF);
        self.erases += 1;
        true
    }

    fn program(&mut self, offset: usize, words: &[u32]) -> bool {
        if self.dead {
            return false;
        }
        assert_eq!(offset % 4, 0, "unaligned program at {offset:#x}");
        assert!(offset + 4 * words.len() <= N, "program past the sector");
        for (i, &w) in words.iter().enumerate() {
            let at = offset + 4 * i;
            let old = self.word(at);
            assert_eq!(
                w & !old,
                0,
                "program at {at:#x} sets a bit: {old:#010x} -> {w:#010x}"
            );
            assert_eq!(old, ERASED, "program of a non-erased word at {at:#x}");
            if self.power == Some(0) {
                self.poke(at, &(old & (w | HALF)).to_le_bytes());
                self.dead = true;
                return false;
            }
            if let Some(p) = &mut self.power {
                *p -= 1;
            }
            self.poke(at, &w.to_le_bytes());
            self.words += 1;
        }
        true
    }
}

/// Words a store of an `n`-byte image programs (the layout's header, image, CRC and commit).
fn words_of(n: usize) -> usize {
    (SLOT_HEADER_LEN + n).div_ceil(4) + 2
}

/// An image of `len` bytes that differs from the images of other seeds.
fn image(seed: usize, len: usize) -> Vec<u8> {
    let mut v: Vec<u8> = (seed as u32).to_le_bytes().to_vec();
    v.extend((0..len).map(|i| (i * 7 + seed * 13) as u8));
    v.truncate(len);
    if len > 0 && len < 4 {
        v[0] = seed as u8;
    }
    v
}

fn load<F: FlashSector>(st: &mut FlashStore<F>) -> Option<Vec<u8>> {
    let mut buf = [0u8; MAX_IMAGE + 16];
    let n = st.load(&mut buf)?;
    assert!(
        n <= MAX_IMAGE,
        "a committed image is at most MAX_IMAGE long"
    );
    Some(buf[..n].to_vec())
}

/// Power back on, a new store over the sector (what init sees), its load.
fn restart_and_load<const N: usize>(ram: &mut Ram<N>) -> Option<Vec<u8>> {
    ram.restart();
    load(&mut FlashStore::new(ram))
}

/// The slot `img` is stored as, written directly (to make garbage from).
fn slot_of(img: &[u8]) -> Vec<u8> {
    encode(img).unwrap().to_vec()
}

#[test]
fn an_erased_sector_loads_nothing() {
    assert_eq!(
        FlashStore::<Ram<SECTOR7>>::SLOTS,
        128,
        "the module doc's count"
    );
    let mut ram = Ram::<SECTOR7>::erased();
    assert_eq!(load(&mut FlashStore::new(&mut ram)), None);
    assert_eq!((ram.words, ram.erases), (0, 0), "load never writes");
    for byte in [0x00, 0xA5] {
        let mut ram = Ram::<SMALL>::filled(byte);
        assert_eq!(
            load(&mut FlashStore::new(&mut ram)),
            None,
            "garbage {byte:#x}"
        );
        assert_eq!((ram.words, ram.erases), (0, 0));
    }
}

#[test]
fn stores_load_back_the_newest() {
    let mut ram = Ram::<SMALL>::erased();
    let lens = [0, 1, 4, RECORD_LEN, MAX_IMAGE, 3, 100];
    for (i, &len) in lens.iter().enumerate() {
        let img = image(i, len);
        let before = ram.words;
        let mut st = FlashStore::new(&mut ram);
        assert!(st.store(&img), "store {i}");
        assert_eq!(load(&mut st), Some(img.clone()), "store {i}");
        assert_eq!(restart_and_load(&mut ram), Some(img.clone()), "store {i}");
        assert_eq!(
            ram.words - before,
            words_of(len),
            "store {i} programs only its words"
        );
        assert_eq!(ram.erases, i / FlashStore::<Ram<SMALL>>::SLOTS, "store {i}");
    }
    // A buffer too short gets what fits and the whole length (the record refuses it).
    let mut st = FlashStore::new(&mut ram);
    let mut buf = [0u8; 3];
    assert_eq!(st.load(&mut buf), Some(100));
    assert_eq!(buf[..], image(lens.len() - 1, 100)[..3]);
}

#[test]
fn the_layout_is_the_documented_one() {
    let mut ram = Ram::<SMALL>::erased();
    let img = image(7, RECORD_LEN);
    let end = SLOT_HEADER_LEN + RECORD_LEN;
    assert!(FlashStore::new(&mut ram).store(&img));
    let s = ram.slot(0).to_vec();
    assert_eq!(&s[0..4], b"MLSL");
    assert_eq!(u16::from_le_bytes([s[4], s[5]]) as usize, RECORD_LEN);
    assert_eq!(u16::from_le_bytes([s[6], s[7]]), SLOT_FORMAT);
    assert_eq!(&s[8..end], &img[..]);
    assert!(
        s[end..CRC_AT].iter().all(|&b| b == 0xFF),
        "padding stays erased"
    );
    assert_eq!(ram.word(CRC_AT), crc32(&s[..end]));
    assert_eq!(&s[COMMIT_AT..SLOT_LEN], b"DONE");
    assert!(ram.mem[SLOT_LEN..].iter().all(|&b| b == 0xFF));
    assert!(FlashStore::new(&mut ram).store(&img));
    assert_eq!(ram.slot(1), &s[..], "the next store takes the next slot");
}

/// `stores` stores of a settings record on `ram`, restarting now and then; the erases they took.
fn wear<const N: usize>(mut ram: Ram<N>, stores: usize) -> usize {
    let mut st = FlashStore::new(&mut ram);
    for i in 0..stores {
        let img = image(i, RECORD_LEN);
        assert!(st.store(&img), "store {i}");
        if i % 97 == 0 {
            st = FlashStore::new(st.into_inner());
        }
        if i % 50 == 0 || i + 1 == stores {
            assert_eq!(load(&mut st), Some(img), "store {i}");
        }
    }
    ram.erases
}

#[test]
fn stores_erase_the_sector_once_per_lap() {
    let slots = FlashStore::<Ram<SECTOR7>>::SLOTS;
    // An erased sector: the first lap needs no erase.
    assert_eq!(
        wear(Ram::<SECTOR7>::erased(), 1000),
        1000usize.div_ceil(slots) - 1
    );
    // A sector of garbage: erased before the first store.
    assert_eq!(
        wear(Ram::<SECTOR7>::filled(0), 1000),
        1000usize.div_ceil(slots)
    );
    let slots = FlashStore::<Ram<SMALL>>::SLOTS;
    assert_eq!(
        wear(Ram::<SMALL>::erased(), 1000),
        1000usize.div_ceil(slots) - 1
    );
}

/// Cuts the power at every word of a store of each length on a copy of `before`: the store fails,
/// `after_cut` loads, and the next two stores work.
fn cut_everywhere<const N: usize>(before: &Ram<N>, after_cut: Option<Vec<u8>>) {
    for len in [0, 5, RECORD_LEN, MAX_IMAGE] {
        let img = image(1000 + len, len);
        let words = words_of(len);
        for k in 0..words {
            let mut ram = before.clone();
            ram.power = Some(k);
            assert!(
                !FlashStore::new(&mut ram).store(&img),
                "len {len}, cut after {k} words"
            );
            // The commit word goes last: no slot the cut store touched reads as committed by
            // it (its CRC is a second guard, not the first).
            for slot in 0..FlashStore::<Ram<N>>::SLOTS {
                if ram.slot(slot) != before.slot(slot) {
                    assert_ne!(
                        ram.word(slot * SLOT_LEN + COMMIT_AT),
                        COMMIT,
                        "len {len}, cut after {k}"
                    );
                }
            }
            assert_eq!(
                restart_and_load(&mut ram),
                after_cut,
                "len {len}, cut after {k}"
            );
            let mut st = FlashStore::new(&mut ram);
            for next in [image(2000, len), image(3000, RECORD_LEN)] {
                assert!(st.store(&next), "len {len}, cut after {k}");
                assert_eq!(
                    load(&mut st),
                    Some(next.clone()),
                    "len {len}, cut after {k}"
                );
            }
            assert_eq!(restart_and_load(&mut ram), Some(image(3000, RECORD_LEN)));
        }
        // With power for all its words, the store is done.
        let mut ram = before.clone();
        ram.power = Some(words);
        assert!(FlashStore::new(&mut ram).store(&img), "len {len}");
        assert_eq!(restart_and_load(&mut ram), Some(img), "len {len}");
    }
}

#[test]
fn a_power_loss_at_any_word_keeps_the_previous_image() {
    let slots = FlashStore::<Ram<SMALL>>::SLOTS;
    // Nothing stored yet.
    cut_everywhere(&Ram::<SMALL>::erased(), None);
    // One image, then all slots but the last used.
    let mut ram = Ram::<SMALL>::erased();
    for i in 0..slots - 1 {
        assert!(FlashStore::new(&mut ram).store(&image(i, RECORD_LEN)));
        cut_everywhere(&ram, Some(image(i, RECORD_LEN)));
    }
    // A full sector: the store erases it first, so a cut loses the settings (the documented
    // window), and the next store works.
    assert!(FlashStore::new(&mut ram).store(&image(9, RECORD_LEN)));
    cut_everywhere(&ram, None);
}

#[test]
fn garbage_slots_are_skipped_never_programmed_over() {
    let a = image(1, RECORD_LEN);
    let b = image(2, 40);
    let c = image(3, RECORD_LEN);
    let mut wrong_crc = slot_of(&b);
    wrong_crc[SLOT_HEADER_LEN + 4] ^= 0x01; // a flipped bit
    let mut too_long = slot_of(&b);
    too_long[4..6].copy_from_slice(&(MAX_IMAGE as u16 + 1).to_le_bytes());
    let mut other_format = slot_of(&b);
    other_format[6] = SLOT_FORMAT as u8 + 1;
    let crc = crc32(&other_format[..SLOT_HEADER_LEN + b.len()]);
    other_format[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
    let mut half_commit = slot_of(&b);
    half_commit[COMMIT_AT..].copy_from_slice(&(COMMIT | HALF).to_le_bytes());
    let mut no_commit = slot_of(&b);
    no_commit[COMMIT_AT..].fill(0xFF);
    let garbage: [(&str, Vec<u8>); 7] = [
        ("one stray word", vec![0; 4]),
        ("random bytes", vec![0xA5; SLOT_LEN]),
        ("wrong CRC", wrong_crc),
        ("length past the slot", too_long),
        ("another slot format", other_format),
        ("half-programmed commit word", half_commit),
        ("no commit word", no_commit),
    ];
    for (what, bytes) in garbage {
        for (at, next) in [(1, 2), (2, 3)] {
            // Slot 0 holds `a`, slot `at` garbage (slot 1 erased when at = 2).
            let mut ram = Ram::<SMALL>::erased();
            assert!(FlashStore::new(&mut ram).store(&a));
            let offset = at * SLOT_LEN + if bytes.len() == 4 { 100 } else { 0 };
            ram.poke(offset, &bytes);
            let dirty = ram.slot(at).to_vec();
            let mut st = FlashStore::new(&mut ram);
            assert_eq!(load(&mut st), Some(a.clone()), "{what} in slot {at}");
            assert!(st.store(&c), "{what} in slot {at}");
            assert_eq!(load(&mut st), Some(c.clone()), "{what} in slot {at}");
            assert_eq!(ram.slot(at), &dirty[..], "{what}: never programmed over");
            assert_eq!(
                ram.slot(next),
                &slot_of(&c)[..],
                "{what}: the slot after it"
            );
            assert_eq!(ram.erases, 0, "{what}");
        }
    }
    // A slot that is not erased although the scan found it so (written behind the store's back
    // after its load): checked again before programming, and skipped.
    let mut st = FlashStore::new(Ram::<SMALL>::erased());
    assert!(st.store(&a));
    assert_eq!(load(&mut st), Some(a.clone()));
    st.sector.poke(SLOT_LEN + 40, &[0; 4]);
    assert!(st.store(&c));
    assert_eq!(st.sector.slot(2), &slot_of(&c)[..]);
    assert_eq!(load(&mut st), Some(c.clone()));
    // Garbage in the last slot: the next store erases the sector.
    let mut ram = Ram::<SMALL>::erased();
    assert!(FlashStore::new(&mut ram).store(&a));
    ram.poke((FlashStore::<Ram<SMALL>>::SLOTS - 1) * SLOT_LEN, &[0; 8]);
    assert_eq!(restart_and_load(&mut ram), Some(a.clone()));
    assert!(FlashStore::new(&mut ram).store(&c));
    assert_eq!((ram.erases, restart_and_load(&mut ram)), (1, Some(c)));
}

#[test]
fn an_image_longer_than_a_slot_is_refused() {
    let mut ram = Ram::<SMALL>::erased();
    let mut st = FlashStore::new(&mut ram);
    assert!(!st.store(&image(1, MAX_IMAGE + 1)));
    assert!(!st.store(&[0; SLOT_LEN]));
    assert_eq!(load(&mut st), None);
    assert_eq!((ram.words, ram.erases), (0, 0), "nothing written");
    // Full sector: a refused image does not erase it.
    for i in 0..FlashStore::<Ram<SMALL>>::SLOTS {
        assert!(FlashStore::new(&mut ram).store(&image(i, MAX_IMAGE)));
    }
    let words = ram.words;
    assert!(!FlashStore::new(&mut ram).store(&image(9, MAX_IMAGE + 1)));
    assert_eq!((ram.words, ram.erases), (words, 0));
    assert_eq!(restart_and_load(&mut ram), Some(image(3, MAX_IMAGE)));
}

#[test]
fn a_refusing_flash_keeps_the_previous_image() {
    let mut ram = Ram::<SMALL>::erased();
    assert!(FlashStore::new(&mut ram).store(&image(1, 10)));
    ram.dead = true;
    assert!(!FlashStore::new(&mut ram).store(&image(2, 10)));
    assert_eq!(load(&mut FlashStore::new(&mut ram)), Some(image(1, 10)));
    // A full sector that does not erase.
    for i in 0..3 {
        ram.dead = false;
        assert!(FlashStore::new(&mut ram).store(&image(i, 10)));
    }
    ram.dead = true;
    assert!(!FlashStore::new(&mut ram).store(&image(5, 10)));
    assert_eq!(restart_and_load(&mut ram), Some(image(2, 10)));
}

/// The settings table over the flash store: a `$N=value` is in the sector and loads at the next
/// start, also after the sector wrapped.
#[test]
fn a_settings_change_loads_back_from_flash() {
    let mut ram = Ram::<SECTOR7>::erased();
    let (mut t, status) = Persistent::load(
        FlashStore::new(&mut ram),
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    assert_eq!(
        (t.settings.get(), status),
        (MachineSettings::default(), LoadStatus::Missing)
    );
    let (n, v) = parse_assignment("$0=7").unwrap();
    assert_eq!(t.set(n, v), Ok(()));
    let changed = t.settings;
    let (back, status) = Persistent::load(
        FlashStore::new(&mut ram),
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    assert_eq!(status, LoadStatus::Loaded);
    assert_eq!(back.settings, changed);
    assert_eq!(back.settings.nc.pulse_width_ns, 7000);
    assert_ne!(back.settings.get(), MachineSettings::default());

    let mut ram = Ram::<SMALL>::erased();
    let (mut t, _) = Persistent::load(
        FlashStore::new(&mut ram),
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    let values = [3, 4, 7, 8, 3, 4, 7, 8, 3, 4];
    for us in values {
        let (n, v) = parse_assignment(&std::format!("$0={us}")).unwrap();
        assert_eq!(t.set(n, v), Ok(()));
    }
    let (back, status) = Persistent::load(
        FlashStore::new(&mut ram),
        crate::settings::BoardLimits::GENERIC,
    )
    .unwrap();
    assert_eq!(status, LoadStatus::Loaded);
    assert_eq!(back.settings.nc.pulse_width_ns, 4000);
    let slots = FlashStore::<Ram<SMALL>>::SLOTS;
    assert_eq!(ram.erases, (values.len() - 1) / slots);
}

#[derive(Clone, Debug)]
enum Op {
    Store(Vec<u8>),
    /// Store with the power cut after that many words (if the store needs more).
    Cut(Vec<u8>, usize),
    Restart,
}

fn op() -> impl Strategy<Value = Op> {
    let img = || prop::collection::vec(any::<u8>(), 0..=MAX_IMAGE + 8);
    prop_oneof![
        3 => img().prop_map(Op::Store),
        2 => (img(), 0..70usize).prop_map(|(v, k)| Op::Cut(v, k)),
        1 => Just(Op::Restart),
    ]
}

proptest! {
    /// Random stores, power losses and restarts on a 4-slot sector: what loads (through a fresh
    /// store, as init) is always the last image whose store completed, or None after a cut that
    /// followed an erase.
    #[test]
    fn the_last_committed_image_loads(ops in prop::collection::vec(op(), 1..40)) {
        let mut st = FlashStore::new(Ram::<SMALL>::erased());
        let mut expected: Option<Vec<u8>> = None;
        for (i, op) in ops.into_iter().enumerate() {
            match op {
                Op::Store(img) => {
                    let ok = st.store(&img);
                    prop_assert_eq!(ok, img.len() <= MAX_IMAGE, "op {}", i);
                    if ok {
                        expected = Some(img);
                    }
                }
                Op::Cut(img, k) => {
                    st.sector.power = Some(k);
                    let erases = st.sector.erases;
                    let ok = st.store(&img);
                    let fits = img.len() <= MAX_IMAGE;
                    prop_assert_eq!(ok, fits && k >= words_of(img.len()), "op {}", i);
                    if ok {
                        expected = Some(img);
                    } else if st.sector.erases > erases {
                        expected = None;
                    }
                    st.sector.restart();
                    st = FlashStore::new(st.into_inner());
                }
                Op::Restart => st = FlashStore::new(st.into_inner()),
            }
            let mut copy = st.sector.clone();
            prop_assert_eq!(load(&mut FlashStore::new(&mut copy)), expected.clone(), "op {}", i);
        }
    }
}
