//! Per-tooth state of the end mill (host): radial run-out and edge damage (chipped or broken
//! teeth) over virtual time, and the chip each tooth takes because of them. [`crate::Process`]
//! keeps one [`Teeth`] (set with its builder methods `with_runout`, `chip_tooth`, `break_tooth`)
//! and asks it for the teeth's radius offsets at every sample; [`crate::process::Cutter::forces`]
//! turns the offsets into chip thicknesses. millac-qemu's `Cut` and its CLI (`--runout`,
//! `--chip-tooth`, `--break-tooth`) set it.
//!
//! Model (the standard static run-out model, e.g. Kline and DeVor 1983, with damage applied
//! causally, see below; Munasinghe 1994 section
//! 3.2 for breakage: "the next tooth has to remove the material the damaged tooth left"):
//! - Tooth k's effective cutting radius is `rho_k = R + runout_k - loss_k(t)`: `runout_k` (mm,
//!   signed, per tooth, default 0) is its radial run-out, `loss_k(t)` the radius its edge has
//!   lost by virtual time t (0 until a chip event, then the deepest chip of that tooth so far; a
//!   broken tooth loses more than any chip it could take: `rho_k = -inf`, it cuts nothing).
//! - Tooth k (preceded by k-1, k-2, ... as the spindle turns) at engagement angle alpha meets the
//!   surface left by the tooth that cut deepest in the last revolution, so its chip is
//!   `h_k = max(0, min over i = 1..z of (i c cos(alpha) + rho_k - rho_{k-i}))` (indices mod z;
//!   i = z is the tooth itself one revolution earlier, so `h_k <= z c cos(alpha)`; broken teeth
//!   are left out of the minimum, they leave no surface). Intact and without run-out this is
//!   `c cos(alpha)`; with tooth j broken, tooth j+1 takes `2 c cos(alpha)`; a tooth with +10 um
//!   run-out takes 10 um more and the tooth after it 10 um less (while `c cos(alpha)` exceeds
//!   10 um); a chip of depth d moves (up to) d of the damaged tooth's chip to the next tooth.
//!   The sum of the chips over one revolution is `z c cos(alpha)` whatever the offsets: the
//!   damage redistributes the material between the teeth, it does not remove more. The
//!   material behind the edge limits every chip: `h_k <= extent cos(alpha)` (entering a wall,
//!   the tooth after a broken one takes what is there, not twice the first tooth's sliver; see
//!   [`crate::process`]).
//! - Causal: tooth k's own offset is the one in force now, and tooth k-i's the one it had when it
//!   passed the same angle, i tooth periods ago (at the spindle speed of now): a tooth that
//!   breaks stops cutting at once, and the next tooth takes its chip from the angle where the
//!   broken tooth stopped cutting on, a tooth period later (the material the broken tooth had cut
//!   before it broke is not cut again). Until issue 20 the model was static (the offsets of the
//!   sample's time applied to every tooth at once), which doubled the next tooth's chip in the
//!   very sample of the break, before the broken tooth's loss: a jump no real fracture makes.
//! - The probe of the axial depth, the engagement angle and the torque's lever arm stay at the
//!   nominal radius R (run-out is microns, a chip tenths of a mm against R = 6.35 mm).
//! - End face (plunges and ramps): the end edges see only breakage. A broken tooth's end edge cuts
//!   nothing and its share goes to the next intact end tooth, the same way as at the side: an
//!   intact end tooth after n broken ones takes `(n + 1) c_z`. Run-out and chips (radial, at the
//!   corner) leave the end face's chips at `c_z`.
//!
//! The default, every tooth intact without run-out, takes the process' original arithmetic (bit
//! for bit the figures from before this model).
use crate::CutError;

/// Default depth of `--chip-tooth` without a depth, mm: a chipped corner of a few hundredths of a
/// millimetre (the size of a typical small edge chip on a HSS end mill; a chip that deep moves
/// about 40 % of a 0.127 mm feed per tooth to the next tooth).
pub const DEFAULT_CHIP_MM: f64 = 0.05;

/// Largest run-out magnitude accepted, mm (a tool that runs out further is not a usable tool).
pub const MAX_RUNOUT_MM: f64 = 1.0;

/// Most flutes a tool may have ([`crate::Tool`]'s check).
pub(crate) const MAX_FLUTES: usize = 32;

/// What happens to a tooth's edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Damage {
    /// The tooth breaks: it cuts nothing from then on (side and end edges).
    Broken,
    /// The edge loses `depth_mm` of radius (finite, >= 0).
    Chipped { depth_mm: f64 },
}

/// Damage to tooth `tooth` (counted from 0 in cutting order, see [`Teeth`]) from virtual time
/// `t_s` on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToothEvent {
    pub tooth: u32,
    pub t_s: f64,
    pub damage: Damage,
}

impl ToothEvent {
    /// Checks the event against a tool of `flutes` teeth.
    pub fn validate(&self, flutes: u32) -> Result<(), CutError> {
        if self.tooth >= flutes {
            return Err(CutError(format!(
                "tooth {} does not exist: the tool has {flutes} teeth, counted from 0 (0..={})",
                self.tooth,
                flutes - 1
            )));
        }
        if !(self.t_s.is_finite() && self.t_s >= 0.0) {
            return Err(CutError(format!(
                "tooth {}: the time of its damage must be finite and >= 0 s, got {}",
                self.tooth, self.t_s
            )));
        }
        if let Damage::Chipped { depth_mm } = self.damage {
            if !(depth_mm.is_finite() && depth_mm >= 0.0) {
                return Err(CutError(format!(
                    "tooth {}: a chip's depth must be finite and >= 0 mm, got {depth_mm}",
                    self.tooth
                )));
            }
        }
        Ok(())
    }
}

/// The teeth's run-out and damage (see the module docs). The default: every tooth intact, no
/// run-out.
///
/// Teeth are counted from 0 in the order they cut: tooth 0 on +X at t = 0, tooth n at the world
/// angle `-theta + n 2 pi / z` (the spindle turns clockwise, so tooth n + 1 follows tooth n, 360 / z
/// degrees behind it: at +90 degrees at t = 0 for z = 4). In [`crate::process`]'s geometric
/// numbering (`psi_g = -theta - g 2 pi / z`) tooth n is `g = (z - n) mod z`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Teeth {
    /// Run-out per tooth, mm (empty = none).
    runout_mm: Vec<f64>,
    /// Damage events in the order given.
    events: Vec<ToothEvent>,
}

impl Teeth {
    /// Sets the run-out of a tool of `flutes` teeth: one value per tooth, mm, finite, within
    /// +-[`MAX_RUNOUT_MM`].
    pub fn set_runout(&mut self, flutes: u32, runout_mm: &[f64]) -> Result<(), CutError> {
        if runout_mm.len() != flutes as usize {
            return Err(CutError(format!(
                "run-out: one value per tooth, the tool has {flutes} teeth, got {} values",
                runout_mm.len()
            )));
        }
        if let Some(v) = runout_mm
            .iter()
            .find(|v| !(v.is_finite() && v.abs() <= MAX_RUNOUT_MM))
        {
            return Err(CutError(format!(
                "run-out must be finite and within +-{MAX_RUNOUT_MM} mm, got {v} mm"
            )));
        }
        self.runout_mm = runout_mm.to_vec();
        Ok(())
    }

    /// Adds a damage event, checked against a tool of `flutes` teeth.
    pub fn add(&mut self, flutes: u32, event: ToothEvent) -> Result<(), CutError> {
        event.validate(flutes)?;
        self.events.push(event);
        Ok(())
    }

    /// The run-out per tooth, mm (empty = none).
    pub fn runout_mm(&self) -> &[f64] {
        &self.runout_mm
    }

    /// The damage events.
    pub fn events(&self) -> &[ToothEvent] {
        &self.events
    }

    /// The radius offsets `rho - R` (mm; -inf = broken) of `flutes` teeth at time `t_s` into
    /// `out[..flutes]`, in the process' geometric numbering (`out[g]`, g = (z - n) mod z for
    /// tooth n); false when every offset is 0 (the intact tool without run-out).
    pub(crate) fn offsets(&self, flutes: u32, t_s: f64, out: &mut [f64; MAX_FLUTES]) -> bool {
        let z = flutes as usize;
        let mut loss = [0.0f64; MAX_FLUTES];
        for e in self.events.iter().filter(|e| e.t_s <= t_s) {
            let k = e.tooth as usize;
            loss[k] = loss[k].max(match e.damage {
                Damage::Broken => f64::INFINITY,
                Damage::Chipped { depth_mm } => depth_mm,
            });
        }
        let mut d = [0.0f64; MAX_FLUTES];
        for n in 0..z {
            let r = self.runout_mm.get(n).copied().unwrap_or(0.0);
            d[(z - n) % z] = if loss[n] == f64::INFINITY {
                f64::NEG_INFINITY
            } else {
                r - loss[n]
            };
        }
        out[..z].copy_from_slice(&d[..z]);
        out[..z].iter().any(|o| *o != 0.0)
    }

    /// The offsets the chips at time `t_s` depend on, with tooth periods of `tooth_s` seconds:
    /// row i (i = 0..=z) the offsets at `t_s - i tooth_s` ([`Self::offsets`]), `(z + 1) z`
    /// values; only the z of now when no damage event falls within the last z tooth periods
    /// (every row the same); 0 when every offset is 0 (the intact tool without run-out). Returns
    /// how many values of `out` it wrote.
    pub(crate) fn history(
        &self,
        flutes: u32,
        t_s: f64,
        tooth_s: f64,
        out: &mut [f64; HISTORY_LEN],
    ) -> usize {
        let z = flutes as usize;
        let mut row = [0.0; MAX_FLUTES];
        let any = self.offsets(flutes, t_s, &mut row);
        out[..z].copy_from_slice(&row[..z]);
        let since = t_s - z as f64 * tooth_s;
        let recent = self.events.iter().any(|e| e.t_s > since && e.t_s <= t_s);
        if !recent {
            return if any { z } else { 0 };
        }
        for i in 1..=z {
            self.offsets(flutes, t_s - i as f64 * tooth_s, &mut row);
            out[i * z..(i + 1) * z].copy_from_slice(&row[..z]);
        }
        (z + 1) * z
    }
}

/// Most values [`Teeth::history`] writes: the offsets of every tooth now and at each of the
/// last `z` tooth periods.
pub(crate) const HISTORY_LEN: usize = MAX_FLUTES * (MAX_FLUTES + 1);

/// The offset of the tooth `i` places before tooth `g` (geometric numbering, `z` teeth) when it
/// passed the angle where `g` is now: from a history ([`Teeth::history`], `(z + 1) z` values,
/// row i the offsets i tooth periods ago) or, from `z` values, the offsets of every tooth now.
fn before(d: &[f64], z: usize, g: usize, i: usize) -> f64 {
    let j = (g + i) % z;
    let row = if d.len() > z { i * z } else { 0 };
    d.get(row + j).copied().unwrap_or(0.0)
}

/// Chip thickness of the tooth of geometric index `g` of `z` (mm) when the intact tool's chip
/// there is `cc = c cos(alpha)` (> 0), with the radius offsets `d` ([`Teeth::history`], or the
/// offsets of all teeth now, [`Teeth::offsets`]; the tooth i places before g in cutting order is
/// g + i mod z).
pub(crate) fn chip_mm(g: usize, z: usize, cc: f64, d: &[f64]) -> f64 {
    if d[g] == f64::NEG_INFINITY {
        return 0.0;
    }
    let mut h = f64::INFINITY;
    for i in 1..=z {
        let prev = before(d, z, g, i);
        if prev == f64::NEG_INFINITY {
            continue;
        }
        h = h.min(i as f64 * cc + d[g] - prev);
    }
    h.max(0.0)
}

/// The end-face chip of the tooth of geometric index `g` of `z` as a multiple of `c_z`: 0 for a
/// broken tooth, else 1 + the number of teeth right before it in cutting order that were broken
/// when they passed (`d` as for [`chip_mm`]).
pub(crate) fn end_share(g: usize, z: usize, d: &[f64]) -> f64 {
    if d[g] == f64::NEG_INFINITY {
        return 0.0;
    }
    let broken_before = (1..z)
        .take_while(|&i| before(d, z, g, i) == f64::NEG_INFINITY)
        .count();
    (broken_before + 1) as f64
}
