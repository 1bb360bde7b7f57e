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
        let fr = f_n * self.r_m;
        if fr < self.floor_nm && t_nm < self.floor_nm {
            return None;
        }
        Some((self.plunging || fr >= self.lo * t_nm) && fr <= self.hi * t_nm)
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
