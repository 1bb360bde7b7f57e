//! The parser's exact length unit (loader task; host tests): 10^-19 mm, "fine units", in which
//! every length word of a program (in mm or inches, up to 18 decimals) is exact; its conversions to
//! and from machine BLU, picometres (the offsets' unit) and words. Called by the line semantics,
//! the offsets and the canned cycles.

use crate::settings::Settings;

/// Fine units per millimetre: 10^-19 mm is an exact common unit of every length word, in mm or in
/// inches (a word has at most 18 decimals, [`super::number::MAX_DECIMALS`], and an inch is 25.4 mm).
pub const FINE_PER_MM: i128 = 10_000_000_000_000_000_000;
/// Fine units per inch (25.4 mm).
pub const FINE_PER_INCH: i128 = 254 * 1_000_000_000_000_000_000;

/// Fine units of `v` program units (`per_fine`: fine units per unit), exact; None on overflow.
#[inline(never)]
pub fn to_fine(v: super::Decimal, per_fine: i128) -> Option<i128> {
    let scale = super::number::pow10(v.scale as u32)?;
    v.mantissa.checked_mul(per_fine.checked_div(scale)?)
}

/// The machine coordinate of a fine position: BLU, rounded half away from zero (the same rounding
/// as a word converted directly), or None when it does not fit i32.
#[inline(never)]
pub fn fine_to_blu(st: &Settings, fine: i128) -> Option<i32> {
    let (num, den) = st.blu.per_mm();
    let n = fine.checked_mul(num as i128)?;
    let d = (den as i128).checked_mul(FINE_PER_MM)?;
    i32::try_from(super::number::div_round(n, d)?).ok()
}

/// BLU of `um` micrometres (the set-up's lengths, `crate::settings::Setup`), rounded as a word
/// is ([`fine_to_blu`]); None when it does not fit i32.
pub fn blu_of_um(st: &Settings, um: i64) -> Option<i32> {
    fine_to_blu(st, fine_of_pm(um.checked_mul(1_000_000)?))
}

/// The fine position of a machine coordinate: exact (1 BLU = 2.54e16 or 1e16 fine units).
pub fn fine_of_blu(st: &Settings, blu: i32) -> i128 {
    let (num, den) = st.blu.per_mm();
    blu as i128 * FINE_PER_MM * den as i128 / num as i128
}

/// Fine units per picometre.
pub const FINE_PER_PM: i128 = FINE_PER_MM / 1_000_000_000;

/// Picometres of a fine length, rounded half away from zero; None when it does not fit i64.
#[inline(never)]
pub fn pm_of_fine(fine: i128) -> Option<i64> {
    i64::try_from(super::number::div_round(fine, FINE_PER_PM)?).ok()
}

/// The fine length of picometres (exact).
pub const fn fine_of_pm(pm: i64) -> i128 {
    pm as i128 * FINE_PER_PM
}
