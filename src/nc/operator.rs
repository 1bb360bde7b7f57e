//! The operator's word: feed override, rapid override, feed hold and abort in one `u32`, written
//! by one context (the loader task, from the protocol's realtime requests) and read once per frame
//! by the frame ISR (`Frame::tick`). One word with one writer: the frame never sees half an update.
//!
//! | bits | meaning |
//! | --- | --- |
//! | 0..=15 | feed factor in Q8 (256 = 100 %; 0 = feed hold): multiplies the feed the frame ramps to |
//! | 16..=18 | rapid mask: a PTP axis pulses only in rapid frames whose count has these bits clear (0 = 100 %, 1 = 50 %, 3 = 25 %) |
//! | 31 | abort: stop at once, drop the queued blocks (soft reset) |

/// Feed factor bits (Q8).
pub const FEED_MASK: u32 = 0xFFFF;
/// Feed factor of 100 %.
pub const FEED_100: u32 = 256;
/// Rapid mask bits start here.
pub const RAPID_SHIFT: u32 = 16;
pub const RAPID_MASK: u32 = 7 << RAPID_SHIFT;
/// Stop at once and drop every queued block.
pub const ABORT: u32 = 1 << 31;
/// Run at 100 % feed and rapid.
pub const RUN: u32 = FEED_100;

/// The word for feed override `feed_pct` (clamped to 1..=200 %), rapid override `rapid_pct`
/// (100, 50 or 25: anything above 50 is 100 %, anything above 25 is 50 %), hold and abort. The
/// feed factor is rounded to the nearest 256th (100 % is exactly 256).
pub const fn word(feed_pct: u8, rapid_pct: u8, hold: bool, abort: bool) -> u32 {
    let pct = if feed_pct > 200 {
        200
    } else if feed_pct == 0 {
        1
    } else {
        feed_pct
    } as u32;
    let feed = if hold { 0 } else { (pct * 256 + 50) / 100 };
    let rapid = if rapid_pct > 50 {
        0
    } else if rapid_pct > 25 {
        1
    } else {
        3
    };
    let abort = if abort { ABORT } else { 0 };
    feed | rapid << RAPID_SHIFT | abort
}

/// The word as the frame must read it while the adaptive controller holds (its feed cap is 0:
/// overload, sensor fault, breakage, chatter, the sampler's trip): held, so a running rapid walks
/// its ladder down and no block starts, exactly as under the operator's hold (a cap of 0 alone
/// stops only the feed). The loaders publish it (`rt::loader`, the QEMU board's program mode)
/// and the host simulation reads it: the frame pays nothing. Loader task, host.
pub const fn with_ac_hold(word: u32, feed_cap: u32) -> u32 {
    if feed_cap == 0 {
        word & !FEED_MASK
    } else {
        word
    }
}

/// Whether the word holds the feed (factor 0). Frame ISR.
#[inline(always)]
pub const fn held(word: u32) -> bool {
    word & FEED_MASK == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words() {
        assert_eq!(word(100, 100, false, false), RUN);
        assert_eq!(word(200, 100, false, false) & FEED_MASK, 512);
        assert_eq!(word(10, 100, false, false) & FEED_MASK, 26);
        assert_eq!(word(255, 100, false, false) & FEED_MASK, 512);
        assert!(held(word(100, 100, true, false)));
        assert!(!held(word(10, 25, false, false)));
        assert_eq!(word(100, 50, false, false) & RAPID_MASK, 1 << RAPID_SHIFT);
        assert_eq!(word(100, 25, false, false) & RAPID_MASK, 3 << RAPID_SHIFT);
        assert_eq!(word(100, 100, false, true) & ABORT, ABORT);
    }
}
