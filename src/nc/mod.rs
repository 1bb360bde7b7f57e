//! The NC program of the paper: blocks, the Initiator, feed DDA, linear and circular DDA
//! interpolators, PTP, output and position counters. Integer only; `Frame::tick` runs in the frame ISR.

pub mod block;
pub mod frame;
pub mod operator;
pub mod sim;
#[cfg(test)]
mod tests;

pub use block::*;
pub use frame::{Frame, FrameConfig, Pulses, Rate};

/// Integer square root: the largest r with r * r <= n. Used by the parser (task) to compute q = L.
pub const fn isqrt(n: u64) -> u64 {
    if n < 2 {
        return n;
    }
    // Newton's iteration from an over-estimate; monotonically decreasing to floor(sqrt(n)).
    let mut x = 1u64 << ((64 - n.leading_zeros()).div_ceil(2));
    loop {
        let y = (x + n / x) / 2;
        if y >= x {
            return x;
        }
        x = y;
    }
}
