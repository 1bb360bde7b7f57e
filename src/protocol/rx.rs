//! Receive side of the serial protocol, split between two contexts: [`RxIsr::push_byte`] runs in
//! the RX interrupt (one byte per call, priority above the loader): it takes realtime bytes out
//! of the stream into flags and override values, and stores every other byte in a lock-free SPSC
//! ring of [`RX_BUFFER_SIZE`] bytes. [`RxTask`] is the loader task's end (read by
//! [`super::Protocol`]). Host tests drive both ends on one thread.
//!
//! Contract with character-counting senders (grbl's RX_BUFFER_SIZE): the ring accepts exactly
//! 128 bytes of unacknowledged lines. A byte pushed into a full ring is never dropped silently:
//! `push_byte` returns [`Push::Refused`], counts it, and *poisons* the ring: every later data
//! byte is refused (and counted) too, until the loader has processed everything stored before
//! the loss and reports [`super::Event::RxOverflow`]. So the bytes in the ring are always an
//! unbroken prefix of what was sent, and the loss has one known position (after them). A soft
//! reset that finds no room for its marker flushes the ring; the data bytes refused after it are
//! counted afresh and reported after the reset, so no line of the new session loses its start
//! unnoticed.
//! Realtime bytes are never stored and never refused.
//!
//! Extended ASCII (bytes 0x80 and above that are not realtime commands) as grbl 1.1 and real
//! senders meet it: bCNC and CNCjs write a realtime byte such as 0x91 as its UTF-8 encoding,
//! `C2 91`. The ISR holds a `C2` back until the next byte: in front of a realtime byte it is
//! dropped (the sender's encoding, not part of any line). An extended byte that arrives between
//! lines (nothing of the next line stored yet: a realtime command of another firmware, a stray
//! encoding byte) is dropped as grbl drops it ([`Push::Dropped`]). Inside a line it is stored,
//! unlike grbl, which drops it there too: a dropped byte could join two digits into another
//! number (`X1\xff0` would become `X10`). The loader refuses a stored byte that is not UTF-8
//! (`error:1`), and UTF-8 text in a comment is accepted.

use core::sync::atomic::{AtomicBool, AtomicU32, AtomicU8, Ordering::Relaxed};
use heapless::spsc::{Consumer, Producer, Queue};

/// Bytes of unacknowledged lines a sender may have in flight (grbl's RX_BUFFER_SIZE).
pub const RX_BUFFER_SIZE: usize = 128;
/// Reset markers the ring holds beside the 128 data bytes: a marker never takes the data's room,
/// so a sender that counts 128 bytes from a banner while a second reset is still queued is not
/// refused. A reset beyond these is handled as one whose marker did not fit (the ring is flushed).
pub const MARKER_SLOTS: usize = 4;
/// heapless' SPSC queue holds N - 1 elements.
const RING: usize = RX_BUFFER_SIZE + MARKER_SLOTS + 1;

/// The realtime command bytes of grbl 1.1.
pub mod byte {
    /// `?` status report request.
    pub const STATUS: u8 = b'?';
    /// `!` feed hold.
    pub const HOLD: u8 = b'!';
    /// `~` cycle start / resume.
    pub const RESUME: u8 = b'~';
    /// ctrl-x soft reset.
    pub const RESET: u8 = 0x18;
    /// Safety door (millac has no door; reported like a hold request).
    pub const DOOR: u8 = 0x84;
    /// Jog cancel.
    pub const JOG_CANCEL: u8 = 0x85;
    /// Feed override: 100 %, +10, -10, +1, -1.
    pub const FEED_100: u8 = 0x90;
    pub const FEED_PLUS_10: u8 = 0x91;
    pub const FEED_MINUS_10: u8 = 0x92;
    pub const FEED_PLUS_1: u8 = 0x93;
    pub const FEED_MINUS_1: u8 = 0x94;
    /// Rapid override: 100, 50, 25 %.
    pub const RAPID_100: u8 = 0x95;
    pub const RAPID_50: u8 = 0x96;
    pub const RAPID_25: u8 = 0x97;
    /// Spindle override: 100 %, +10, -10, +1, -1.
    pub const SPINDLE_100: u8 = 0x99;
    pub const SPINDLE_PLUS_10: u8 = 0x9A;
    pub const SPINDLE_MINUS_10: u8 = 0x9B;
    pub const SPINDLE_PLUS_1: u8 = 0x9C;
    pub const SPINDLE_MINUS_1: u8 = 0x9D;
    /// Spindle stop, flood and mist coolant toggles: taken out of the stream, no effect in millac.
    pub const SPINDLE_STOP: u8 = 0x9E;
    pub const FLOOD: u8 = 0xA0;
    pub const MIST: u8 = 0xA1;

    /// Whether `b` is a realtime byte (never stored, wherever it appears in a line).
    pub const fn is_realtime(b: u8) -> bool {
        matches!(
            b,
            STATUS | HOLD | RESUME | RESET | DOOR | JOG_CANCEL | 0x90..=0x97 | 0x99..=0x9E | FLOOD | MIST
        )
    }
}

/// Override limits and steps (grbl's defaults).
pub const FEED_OV_MIN: u8 = 10;
pub const FEED_OV_MAX: u8 = 200;

/// Current override values in percent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Overrides {
    /// Feed override, 10..=200.
    pub feed: u8,
    /// Rapid override: 100, 50 or 25.
    pub rapid: u8,
    /// Spindle override, 10..=200 (reported only: millac does not drive a spindle).
    pub spindle: u8,
}

impl Overrides {
    pub const NONE: Overrides = Overrides {
        feed: 100,
        rapid: 100,
        spindle: 100,
    };
}

/// Pending realtime requests, as the loader takes them (each bit set at most once however often
/// its byte came: a second `?` before the first is served is one request, as in grbl).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pending(pub u8);

impl Pending {
    pub const STATUS: u8 = 1;
    pub const HOLD: u8 = 1 << 1;
    pub const RESUME: u8 = 1 << 2;
    pub const JOG_CANCEL: u8 = 1 << 3;
    pub const DOOR: u8 = 1 << 4;
    /// An override value changed (read them with `Protocol::overrides`).
    pub const OVERRIDES: u8 = 1 << 5;

    /// `?`: send a status report (`Protocol::status_report`).
    pub const fn status(self) -> bool {
        self.0 & Self::STATUS != 0
    }
    /// `!`: feed hold.
    pub const fn hold(self) -> bool {
        self.0 & Self::HOLD != 0
    }
    /// `~`: cycle start / resume.
    pub const fn resume(self) -> bool {
        self.0 & Self::RESUME != 0
    }
    /// 0x85: jog cancel.
    pub const fn jog_cancel(self) -> bool {
        self.0 & Self::JOG_CANCEL != 0
    }
    /// 0x84: safety door (millac: treat as a feed hold).
    pub const fn door(self) -> bool {
        self.0 & Self::DOOR != 0
    }
    /// 0x90..0x97, 0x99..0x9D changed an override value.
    pub const fn overrides(self) -> bool {
        self.0 & Self::OVERRIDES != 0
    }
}

/// The words both ends share. Relaxed atomics: one core; each word means something on its own.
struct Flags {
    /// [`Pending`] bits, set by the ISR (`fetch_or`), taken by the loader (`swap(0)`).
    pending: AtomicU8,
    /// Soft resets received and not yet handled by the loader. Each stored reset is also a marker
    /// byte (0x18) in the ring at its position in the stream.
    resets: AtomicU8,
    /// Reset markers in the ring (at most [`MARKER_SLOTS`]): incremented by the ISR when it stores
    /// one, decremented by the loader when it takes one; the data bytes in the ring are its
    /// length minus these.
    markers: AtomicU8,
    /// A byte (or reset marker) did not fit: refuse data bytes until the loader clears it.
    poisoned: AtomicBool,
    /// Data bytes refused since the loader last looked.
    lost: AtomicU32,
    /// Nothing of the current line stored yet (the last data byte stored ended a line, or a
    /// reset came). ISR only.
    line_start: AtomicBool,
    /// A UTF-8 lead byte `C2` was held back: it is dropped if a realtime byte follows, otherwise
    /// handled as an extended byte in front of the next one. ISR only.
    lead: AtomicBool,
    /// Override values; written by the ISR only.
    feed: AtomicU8,
    rapid: AtomicU8,
    spindle: AtomicU8,
}

/// The receive state shared by the RX interrupt and the loader. The firmware keeps one in a
/// `static` (or an RTIC local with `'static` lifetime) and [`split`](Self::split)s it once in init.
pub struct RxShared {
    ring: Queue<u8, RING>,
    flags: Flags,
}

impl Default for RxShared {
    fn default() -> Self {
        Self::new()
    }
}

impl RxShared {
    pub const fn new() -> Self {
        RxShared {
            ring: Queue::new(),
            flags: Flags {
                pending: AtomicU8::new(0),
                resets: AtomicU8::new(0),
                markers: AtomicU8::new(0),
                poisoned: AtomicBool::new(false),
                lost: AtomicU32::new(0),
                line_start: AtomicBool::new(true),
                lead: AtomicBool::new(false),
                feed: AtomicU8::new(100),
                rapid: AtomicU8::new(100),
                spindle: AtomicU8::new(100),
            },
        }
    }

    /// The interrupt's end and the loader's end.
    pub fn split(&mut self) -> (RxIsr<'_>, RxTask<'_>) {
        let (p, c) = self.ring.split();
        let flags = &self.flags;
        (RxIsr { ring: p, flags }, RxTask { ring: c, flags })
    }
}

/// What [`RxIsr::push_byte`] did with a byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Push {
    /// A data byte, stored in the ring.
    Stored,
    /// A realtime byte: taken out of the stream (flag, override or reset set). The firmware may
    /// act on it at once (e.g. stop the feed on `!` or 0x18) before the loader sees it.
    Realtime(u8),
    /// The ring was full (or poisoned by an earlier loss): the byte was not stored. It is counted,
    /// and the loader will report [`super::Event::RxOverflow`]; a sender that keeps the
    /// character-counting contract never sees this.
    Refused,
    /// An extended-ASCII byte that is no realtime command, between lines, or a UTF-8 lead byte
    /// `C2` held back (dropped if a realtime byte follows): not stored, not an error (grbl
    /// drops them too). See the module doc.
    Dropped,
}

/// The UTF-8 lead byte of U+0080..U+00BF, where all of grbl's extended realtime bytes lie.
const UTF8_LEAD_C2: u8 = 0xC2;

/// The RX interrupt's end: one call per received byte. No locks, no loops, no panics.
pub struct RxIsr<'a> {
    ring: Producer<'a, u8, RING>,
    flags: &'a Flags,
}

impl RxIsr<'_> {
    /// Takes one received byte (RX interrupt).
    pub fn push_byte(&mut self, b: u8) -> Push {
        let f = self.flags;
        if byte::is_realtime(b) {
            // A `C2` held back in front of it was the sender's UTF-8 encoding: dropped.
            f.lead.store(false, Relaxed);
            match b {
                byte::RESET => {
                    // The reset acts at its place in the stream: lines before it are discarded,
                    // bytes after it belong to the new session. The marker tells the loader where.
                    f.resets
                        .store(f.resets.load(Relaxed).saturating_add(1), Relaxed);
                    f.line_start.store(true, Relaxed);
                    f.feed.store(100, Relaxed);
                    f.rapid.store(100, Relaxed);
                    f.spindle.store(100, Relaxed);
                    let markers = f.markers.load(Relaxed);
                    if f.poisoned.load(Relaxed)
                        || markers as usize >= MARKER_SLOTS
                        || self.ring.enqueue(byte::RESET).is_err()
                    {
                        // No room for the marker: the loader flushes the whole ring instead.
                        // Bytes lost before the reset do not matter (their lines are discarded
                        // with it); the count starts again, so the data bytes refused from now on,
                        // the new session's, are reported after the flush.
                        f.poisoned.store(true, Relaxed);
                        f.lost.store(0, Relaxed);
                    } else {
                        f.markers.store(markers + 1, Relaxed);
                    }
                }
                byte::STATUS => self.pend(Pending::STATUS),
                byte::HOLD => self.pend(Pending::HOLD),
                byte::RESUME => self.pend(Pending::RESUME),
                byte::JOG_CANCEL => self.pend(Pending::JOG_CANCEL),
                byte::DOOR => self.pend(Pending::DOOR),
                0x90..=0x94 => self.step_feed(b),
                byte::RAPID_100 | byte::RAPID_50 | byte::RAPID_25 => {
                    let v = match b {
                        byte::RAPID_100 => 100,
                        byte::RAPID_50 => 50,
                        _ => 25,
                    };
                    self.set_ov(&f.rapid, v);
                }
                0x99..=0x9D => self.step_spindle(b),
                _ => {} // spindle stop, coolant toggles: nothing to do in millac
            }
            return Push::Realtime(b);
        }
        if f.lead.load(Relaxed) {
            // The held `C2` is followed by a byte that is no realtime command: it was text.
            f.lead.store(false, Relaxed);
            if self.data(UTF8_LEAD_C2) == Push::Refused {
                // Poisoned now: the byte after it is refused and counted as well.
                return self.data(b);
            }
        }
        if b == UTF8_LEAD_C2 {
            f.lead.store(true, Relaxed);
            return Push::Dropped;
        }
        self.data(b)
    }

    /// A data byte: an extended byte between lines is dropped, any other byte stored (or
    /// refused when the ring is full or poisoned).
    fn data(&mut self, b: u8) -> Push {
        let f = self.flags;
        if b >= 0x80 && f.line_start.load(Relaxed) {
            return Push::Dropped;
        }
        // The data bytes in the ring: its length without the reset markers (the loader may have
        // taken a marker and not yet counted it: then one byte more is let in, never fewer).
        let data = self
            .ring
            .len()
            .saturating_sub(f.markers.load(Relaxed) as usize);
        if f.poisoned.load(Relaxed) || data >= RX_BUFFER_SIZE || self.ring.enqueue(b).is_err() {
            f.poisoned.store(true, Relaxed);
            f.lost
                .store(f.lost.load(Relaxed).saturating_add(1), Relaxed);
            return Push::Refused;
        }
        f.line_start.store(b == b'\n' || b == b'\r', Relaxed);
        Push::Stored
    }

    /// `n` bytes the hardware lost before they reached [`RxIsr::push_byte`] (a receiver overrun:
    /// the UART's data register was overwritten). They count and poison the ring exactly like
    /// refused bytes, so the loader reports [`super::Event::RxOverflow`] (`ALARM:110`): the
    /// sender's stream is out of step. RX interrupt.
    pub fn lost_bytes(&mut self, n: u32) {
        let f = self.flags;
        f.poisoned.store(true, Relaxed);
        f.lost
            .store(f.lost.load(Relaxed).saturating_add(n), Relaxed);
    }

    fn pend(&self, bit: u8) {
        self.flags.pending.fetch_or(bit, Relaxed);
    }

    fn set_ov(&self, word: &AtomicU8, v: u8) {
        if word.load(Relaxed) != v {
            word.store(v, Relaxed);
            self.pend(Pending::OVERRIDES);
        }
    }

    fn step_feed(&self, b: u8) {
        let v = step(self.flags.feed.load(Relaxed), b - byte::FEED_100);
        self.set_ov(&self.flags.feed, v);
    }

    fn step_spindle(&self, b: u8) {
        let v = step(self.flags.spindle.load(Relaxed), b - byte::SPINDLE_100);
        self.set_ov(&self.flags.spindle, v);
    }
}

/// One override step: 0 = 100 %, 1 = +10, 2 = -10, 3 = +1, 4 = -1; clamped to 10..=200.
const fn step(v: u8, k: u8) -> u8 {
    let v = match k {
        0 => 100,
        1 => v.saturating_add(10),
        2 => v.saturating_sub(10),
        3 => v.saturating_add(1),
        _ => v.saturating_sub(1),
    };
    if v < FEED_OV_MIN {
        FEED_OV_MIN
    } else if v > FEED_OV_MAX {
        FEED_OV_MAX
    } else {
        v
    }
}

/// The loader's end of the ring (owned by [`super::Protocol`]).
pub struct RxTask<'a> {
    ring: Consumer<'a, u8, RING>,
    flags: &'a Flags,
}

impl RxTask<'_> {
    pub(crate) fn pop(&mut self) -> Option<u8> {
        self.ring.dequeue()
    }

    /// Free bytes in the ring (the `Bf:` field's second value).
    pub fn available(&self) -> usize {
        let data = self
            .ring
            .len()
            .saturating_sub(self.flags.markers.load(Relaxed) as usize);
        RX_BUFFER_SIZE.saturating_sub(data)
    }

    pub(crate) fn take_pending(&self) -> Pending {
        Pending(self.flags.pending.swap(0, Relaxed))
    }

    pub(crate) fn resets_pending(&self) -> bool {
        self.flags.resets.load(Relaxed) != 0
    }

    /// One reset handled (its marker was found in the ring).
    pub(crate) fn reset_done(&self) {
        // Only the ISR increments; these read-modify-writes run with the counts above 0.
        self.flags.markers.fetch_sub(1, Relaxed);
        self.flags.resets.fetch_sub(1, Relaxed);
    }

    /// A reset whose marker did not fit: everything up to now is flushed and every pending reset
    /// handled. Returns the data bytes refused since the (last) reset: they belonged to the new
    /// session, so the caller reports them like any loss (0: nothing was lost after it).
    pub(crate) fn reset_flush(&mut self) -> u32 {
        // The ring is poisoned here (the marker did not fit), so the ISR stores nothing, marker
        // or data, until `clear_loss` lifts the poison.
        while self.ring.dequeue().is_some() {}
        self.flags.markers.store(0, Relaxed);
        self.flags.resets.store(0, Relaxed);
        self.clear_loss()
    }

    /// Whether the ring refused bytes (poisoned).
    pub(crate) fn poisoned(&self) -> bool {
        self.flags.poisoned.load(Relaxed)
    }

    /// Clears the poison once the ring is drained; returns the bytes lost. Bytes the ISR refuses
    /// until the poison is cleared are still counted in the value returned.
    pub(crate) fn clear_loss(&self) -> u32 {
        self.flags.poisoned.store(false, Relaxed);
        self.flags.lost.swap(0, Relaxed)
    }

    /// The override values (written by the ISR).
    pub fn overrides(&self) -> Overrides {
        Overrides {
            feed: self.flags.feed.load(Relaxed),
            rapid: self.flags.rapid.load(Relaxed),
            spindle: self.flags.spindle.load(Relaxed),
        }
    }
}
