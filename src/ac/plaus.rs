//! Force/torque plausibility (beyond the paper): in a cut the resultant force F and the torque T
//! come from the same chips, so F*R/T (R the cutter radius) stays inside a band the tool geometry
//! sets (see [`super::AcSettings::ft_ratio_min`]). Used by the DRR for every sample that jumps (a
//! jump the torque does not confirm is a sensor fault) and by the controller every AC period on
//! the window's peaks (a gain fault: a loose transducer). Called from the AC task.
//!
//! The band's lower end holds only where the cut is side milling. The end face of a flat end
//! mill cuts where the tool feeds down (a plunge, a ramp, a helix): it makes torque with almost
//! no net radial force (F*R/T near 0 in a plunge), a legitimate cut the lower end would call a
//! gain fault. While the Z axis feeds down (and for the held peak's windows after it) the
//! controller judges only the upper end ([`Band::plunging`]): no cut makes F*R/T above
//! sqrt(1 + Kr^2), whatever its engagement, so a force that reads double, or a torque that
//! reads half, is still caught there.
//!
//! Cost: three f32 multiplications and four comparisons, no division.

use super::settings::AcSettings;

/// The F*R/T band and the floor below which a load is too small to judge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    /// Cutter radius in m (F in N times R in m is N*m, like T).
    r_m: f32,
    lo: f32,
    hi: f32,
    floor_nm: f32,
    /// The Z axis feeds down: the lower end is not judged (see the module doc).
    plunging: bool,
}

/// The part of the force the holder's frame (Fu, Fv turn with the spindle) may move it between
/// two samples with no change of load: 2 sin(10 deg), a turn of 20 degrees per sample (3300 rpm
/// at the default 1 kHz).
pub const FRAME_TURN: f32 = 0.35;

impl Band {
    pub fn new(s: &AcSettings) -> Self {
        Band {
            r_m: s.tool_radius_mm / 1000.0,
            lo: s.ft_ratio_min,
            hi: s.ft_ratio_max,
            floor_nm: s.ft_floor_nm,
            plunging: false,
        }
    }

    /// Whether the end face may be cutting (the Z axis fed down in the last AC periods): then
    /// only the band's upper end is judged. AC task, once per period.
    pub fn plunging(&mut self, on: bool) {
        self.plunging = on;
    }

    /// Judges F (N) against |T| (N*m): `None` when both T and F*R are below the floor (nothing to
    /// judge: air, noise), `Some(true)` when F*R/T is inside the band, `Some(false)` outside (also
    /// a force with no torque, or a torque with no force).
    #[inline]
    pub fn judge(&self, f_n: f32, t_nm: f32) -> Option<bool> {
        self.judge_ends(f_n, t_nm, self.plunging)
    }

    /// Whether a jump from the sample `from` to `to` (T, Fu, Fv in N*m and N) is one that load
    /// can make: the force vector may not move by more than the band's upper end allows for the
    /// torque's change, plus the floor (noise) and the turn of the holder's frame between two
    /// samples ([`FRAME_TURN`] of the larger force). A tooth whose chip changes moves F by
    /// sqrt(1 + Kr^2) times its tangential force and T by R times it; a spike on Fu or Fv moves F
    /// alone, also when the new total still looks like a cut (a loaded tool at F*R/T = 0.75 with
    /// Fu 2000 N higher reads 1.2; Fu -3600 N spiking to +3900 N keeps F). Judged on jumps only
    /// (a code moved by more than `jump_codes`), where the frame's turn is small beside it. The
    /// torque's own jumps are judged by the totals ([`Band::judge`]): at a plunge's end face T
    /// moves with no force. AC task (the DRR), per jumped sample.
    #[inline]
    pub fn step_plausible(&self, from: (f32, f32, f32), to: (f32, f32, f32)) -> bool {
        let (t0, u0, v0) = from;
        let (t1, u1, v1) = to;
        let df = crate::ac::ecr::force(u1 - u0, v1 - v0);
        let f = crate::ac::ecr::force(u0, v0).max(crate::ac::ecr::force(u1, v1));
        let dt = if t1.abs() > t0.abs() {
            t1.abs() - t0.abs()
        } else {
            t0.abs() - t1.abs()
        };
        df * self.r_m <= self.hi * dt + self.floor_nm + FRAME_TURN * f * self.r_m
    }

    /// As [`Band::judge`] with both ends judged also while plunging: for a sample with a channel
    /// at its rail, whose value is only a bound (T at the rail in a plunge is the `rail` fault's
    /// signature, not an end face: no end face makes the torque's full scale within a sample).
    #[inline]
    pub fn judge_both_ends(&self, f_n: f32, t_nm: f32) -> Option<bool> {
        self.judge_ends(f_n, t_nm, false)
    }

    /// The judgement of both: the lower end waived when `upper_only`.
    #[inline]
    fn judge_ends(&self, f_n: f32, t_nm: f32, upper_only: bool) -> Option<bool> {
        let fr = f_n * self.r_m;
        if fr < self.floor_nm && t_nm < self.floor_nm {
            return None;
        }
        Some((upper_only || fr >= self.lo * t_nm) && fr <= self.hi * t_nm)
    }

    /// F*R/T for a report (infinity for T = 0).
    pub fn ratio(&self, f_n: f32, t_nm: f32) -> f32 {
        if t_nm > 0.0 {
            f_n * self.r_m / t_nm
        } else {
            f32::INFINITY
        }
    }
}
