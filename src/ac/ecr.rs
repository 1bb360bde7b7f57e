//! ECR, the Error Calculator Routine: the resultant force F = sqrt(Fu^2 + Fv^2), the errors
//! Ef = 1 - F/F0 and Et = 1 - T/T0 (the paper's Eq. 5) and the critical error E, the smaller of
//! the two ("the smaller positive or greater negative"). Called from the AC task every AC period
//! (and `force` from the DRR for every sample).

/// Resultant of the two perpendicular force components, in their unit. `libm::sqrtf` is correctly
/// rounded, so host and target give the same bits.
#[inline]
pub fn force(fu: f32, fv: f32) -> f32 {
    libm::sqrtf(fu * fu + fv * fv)
}

/// The errors of one AC period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    /// Ef = 1 - F/F0.
    pub ef: f32,
    /// Et = 1 - T/T0.
    pub et: f32,
    /// The critical error: min(Ef, Et).
    pub e: f32,
}

/// Errors of a measured F (N) and T (N*m) against the optimal values F0, T0 (> 0, validated).
#[inline]
pub fn errors(f_n: f32, t_nm: f32, f0_n: f32, t0_nm: f32) -> Errors {
    let ef = 1.0 - f_n / f0_n;
    let et = 1.0 - t_nm / t0_nm;
    Errors {
        ef,
        et,
        e: if et < ef { et } else { ef },
    }
}
