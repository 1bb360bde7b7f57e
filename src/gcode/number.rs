//! Exact decimal numbers of G-code words and their conversion to integers (BLU, feed numbers,
//! frames) by rational arithmetic with rounding half away from zero. Called by the G-code parser
//! (loader task) and the host tests; no floats, no panics.

use core::fmt;

/// Most integer digits a word may have (leading zeros not counted).
pub const MAX_INT_DIGITS: u32 = 20;
/// Most decimal places a word may have (trailing zeros not counted).
pub const MAX_DECIMALS: u32 = 18;

/// An exact decimal: `mantissa / 10^scale`. Trailing fractional zeros are dropped when parsing, so
/// an integral value always has `scale == 0`. |mantissa| < 10^38.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decimal {
    pub mantissa: i128,
    pub scale: u8,
}

impl Decimal {
    pub const fn int(v: i64) -> Self {
        Decimal {
            mantissa: v as i128,
            scale: 0,
        }
    }

    pub const fn is_negative(self) -> bool {
        self.mantissa < 0
    }

    pub const fn is_zero(self) -> bool {
        self.mantissa == 0
    }

    /// The value if it is a whole number.
    pub fn as_integer(self) -> Option<i128> {
        if self.scale == 0 {
            Some(self.mantissa)
        } else {
            None
        }
    }

    /// The f32 nearest the decimal, ties to even (as core's parser gives it), by exact integer
    /// arithmetic: q = m 2^k / 10^s scaled into [2^23, 2^24), rounded, times 2^-k. None outside
    /// the normal f32 range. (core's `f32::from_str` would bring its 10 KiB power table into the
    /// firmware.)
    pub fn to_f32(self) -> Option<f32> {
        let m = self.mantissa.unsigned_abs();
        if m == 0 {
            return Some(0.0);
        }
        let d = 10u128.checked_pow(self.scale as u32)?;
        let bits = |v: u128| 128 - v.leading_zeros() as i32;
        // m 2^k / d lands within a factor of 2 of 2^23 for this k; the loop settles it.
        let mut k = 24 - bits(m) + bits(d);
        for _ in 0..4 {
            let (num, den) = if k >= 0 {
                (m.checked_shl(k as u32).filter(|n| n >> k == m)?, d)
            } else {
                (m, d.checked_shl((-k) as u32).filter(|n| n >> -k == d)?)
            };
            let q = num / den;
            if q >= 1 << 24 {
                k -= 1;
                continue;
            }
            if q < 1 << 23 {
                k += 1;
                continue;
            }
            let r = num % den;
            let q = if 2 * r > den || (2 * r == den && q & 1 == 1) {
                q + 1
            } else {
                q
            };
            // 2^-k exactly, in the normal range.
            let e = 127 - k;
            if !(1..=254).contains(&e) {
                return None;
            }
            let v = q as f32 * f32::from_bits((e as u32) << 23);
            return Some(if self.mantissa < 0 { -v } else { v });
        }
        None
    }

    /// round(self * num / den), half away from zero; `None` on overflow or den <= 0.
    pub fn mul_ratio_round(self, num: i128, den: i128) -> Option<i128> {
        let n = self.mantissa.checked_mul(num)?;
        let d = pow10(self.scale as u32)?.checked_mul(den)?;
        div_round(n, d)
    }
}

/// 10^e as i128, `None` if it does not fit.
pub fn pow10(e: u32) -> Option<i128> {
    10i128.checked_pow(e)
}

/// round(n / d), half away from zero; `None` on overflow or d <= 0.
pub fn div_round(n: i128, d: i128) -> Option<i128> {
    if d <= 0 {
        return None;
    }
    let a = n.checked_abs()?;
    let q = a.checked_mul(2)?.checked_add(d)? / d.checked_mul(2)?;
    Some(if n < 0 { -q } else { q })
}

/// round(sqrt(n)) with integers: floor root k, plus one when n > k^2 + k (then n >= (k + 1/2)^2).
pub fn round_sqrt(n: u64) -> u64 {
    let k = crate::nc::isqrt(n);
    // k^2 <= n < (k+1)^2 <= 2^64, so n - k*k <= 2k and k*k cannot overflow.
    if n - k * k > k {
        k + 1
    } else {
        k
    }
}

/// Whether an f32 can be listed and read back exactly: its shortest decimal (core's `{}`) has at
/// most 13 integer digits and 15 decimals, inside what [`parse_decimal`] reads. The settings
/// table's f32 settings and the tool table's limits are held to it.
pub fn listable_f32(v: f32) -> bool {
    v == 0.0 || (v.is_finite() && (1e-6..=1e12).contains(&v.abs()))
}

impl fmt::Display for Decimal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.mantissa.unsigned_abs();
        let p = 10u128.pow(self.scale.min(38) as u32);
        if self.mantissa < 0 {
            f.write_str("-")?;
        }
        write!(f, "{}", a / p)?;
        if self.scale > 0 {
            write!(f, ".{:0w$}", a % p, w = self.scale as usize)?;
        }
        Ok(())
    }
}

/// Why a number could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumError {
    Malformed,
    TooLarge,
    TooManyDecimals,
}

/// Incremental reader of `[+-]? digits [. digits]`, fed one character at a time.
#[derive(Default)]
pub struct DecimalReader {
    negative: bool,
    signed: bool,
    dot: bool,
    digits: bool,
    mantissa: i128,
    int_digits: u32,
    scale: u32,
    pending_zeros: u32,
}

impl DecimalReader {
    /// Whether `c` belongs to the number (a misplaced sign or dot belongs to it and makes it
    /// malformed in `push`).
    pub fn accepts(&self, c: char) -> bool {
        matches!(c, '0'..='9' | '.' | '+' | '-')
    }

    /// Whether anything was read.
    pub fn started(&self) -> bool {
        self.signed || self.dot || self.digits
    }

    /// Feeds one character that `accepts` returned true for.
    pub fn push(&mut self, c: char) -> Result<(), NumError> {
        match c {
            '+' | '-' if !self.started() => {
                self.signed = true;
                self.negative = c == '-';
            }
            '.' if !self.dot => self.dot = true,
            '0'..='9' => {
                self.digits = true;
                let d = c as i128 - '0' as i128;
                if !self.dot {
                    if self.mantissa == 0 && d == 0 {
                        return Ok(());
                    }
                    self.int_digits += 1;
                    if self.int_digits > MAX_INT_DIGITS {
                        return Err(NumError::TooLarge);
                    }
                    self.mantissa = self.mantissa * 10 + d;
                } else if d == 0 {
                    self.pending_zeros = self.pending_zeros.saturating_add(1);
                } else {
                    let add = self.pending_zeros.saturating_add(1);
                    if self.scale.saturating_add(add) > MAX_DECIMALS {
                        return Err(NumError::TooManyDecimals);
                    }
                    let p = pow10(add).ok_or(NumError::TooManyDecimals)?;
                    // |mantissa| < 10^20 * 10^18: fits.
                    self.mantissa = self.mantissa.checked_mul(p).ok_or(NumError::TooLarge)? + d;
                    self.scale += add;
                    self.pending_zeros = 0;
                }
            }
            _ => return Err(NumError::Malformed),
        }
        Ok(())
    }

    /// The number read, if it had at least one digit.
    pub fn finish(&self) -> Result<Decimal, NumError> {
        if !self.digits {
            return Err(NumError::Malformed);
        }
        let m = if self.negative {
            -self.mantissa
        } else {
            self.mantissa
        };
        Ok(Decimal {
            mantissa: m,
            scale: self.scale as u8,
        })
    }
}

/// Parses a whole string as one number (tests and tools).
pub fn parse_decimal(s: &str) -> Result<Decimal, NumError> {
    let mut r = DecimalReader::default();
    for c in s.chars() {
        if !r.accepts(c) {
            return Err(NumError::Malformed);
        }
        r.push(c)?;
    }
    r.finish()
}
