//! FRC, the Feed-Rate Calculator: the paper's strategy (Fig. 7) and the feed update (Eq. 8).
//! Called from the AC task every AC period.
//!
//! E >= 0: fdot = fdot_m * E^2 (Eq. 6); E < 0: fdot = -fdot_m * (10 E)^2 (Eq. 7);
//! f(t + dt) = f(t) + fdot * dt (Eq. 8), clamped to [f_min, f_max].
//!
//! Dead zone. The paper notes that fdot is zero near E = 0 because the computer works with
//! discrete numbers, and that this natural dead zone stabilises the loop. Here it is the same
//! quantisation, made explicit: the feed is an integer feed number (0.01 ipm at the paper's
//! scale) and the change of one period, fdot * dt in feed numbers, is truncated toward zero, so
//! changes smaller than one feed number are dropped. With fdot_m * dt = 750 feed numbers
//! (750 ipm/s, 10 ms) the dead zone is -0.00365 < E < 0.0365 (see [`dead_zone`]); it is
//! asymmetric like the strategy, and a static process settles inside it from below.

/// Fig. 7: the feed acceleration for a critical error `e`, in the unit of `fdot_m`.
#[inline]
pub fn fdot(e: f32, fdot_m: f32) -> f32 {
    if e >= 0.0 {
        fdot_m * e * e
    } else {
        let x = 10.0 * e;
        -fdot_m * x * x
    }
}

/// Eq. 8 on integer feed numbers: the feed after one AC period. `step` is fdot_m * dt in feed
/// numbers (750 at defaults). The change is truncated toward zero (the dead zone), the result
/// clamped to [f_min, f_max]. A NaN `e` (impossible with validated settings) leaves f unchanged.
#[inline]
pub fn next_feed(f: u32, e: f32, step: f32, f_min: u32, f_max: u32) -> u32 {
    // `as` truncates toward zero, saturates at the i32 range and maps NaN to 0.
    let d = fdot(e, step) as i32;
    let n = f as i64 + d as i64;
    if n < f_min as i64 {
        f_min
    } else if n > f_max as i64 {
        f_max
    } else {
        n as u32
    }
}

/// The dead zone (e_neg, e_pos): for e_neg < E < e_pos one period changes f by less than one feed
/// number, so f stays. e_pos = sqrt(1/step), e_neg = -e_pos/10.
pub fn dead_zone(step: f32) -> (f32, f32) {
    let e = libm::sqrtf(1.0 / step);
    (-e / 10.0, e)
}
