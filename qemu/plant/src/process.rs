//! The cutting process sampled at the ADC rate (host). [`Process::sample`] takes the time and the
//! tool tip position (BLU, from the step pulses counted so far), computes the instantaneous force
//! and torque from the engagement at that instant, removes the material swept since the previous
//! sample and returns the true values and the ADC codes.
//!
//! Model (Munasinghe 1994, eq. 3.1 to 3.5; straight flutes, see [`crate::Tool`]):
//! - Spindle clockwise seen from above (M3). Spindle angle `theta = 2 pi rpm t / 60`; tooth k sits
//!   at the world angle `psi_k = -theta - k 2 pi / z` (counter-clockwise from +X), tooth 0 on +X
//!   at t = 0.
//! - Feed per tooth `c` and feed direction `u` (XY) from the tool motion over the last tooth
//!   period `60 / (rpm z)` (the chip is the material between this tooth's path and the previous
//!   one's): `c = |d_xy| / (z rpm / 60 * dt)`. The window also smooths the BLU quantisation of
//!   the position. Z motion down makes the end-face chip `c_z = -dz / (z rpm / 60 * dt)` (below).
//! - Side teeth: the chip a tooth takes is the material between its path and the previous
//!   tooth's path, on the line along the feed through its edge. The process cuts the stock at
//!   every sample, so by the time a tooth comes round that material is mostly gone from the
//!   height map; what the map keeps is its memory (see [`crate::stock`]): each cell knows at which
//!   point of the tool's XY path (the stock's odometer) the tool last lowered it. Along the line
//!   a cell is material (its top above `base = max(tip Z, floor)`), air the tool made recently
//!   (lowered within the last `L` mm of path: the material this swath is taking) or old air (air
//!   before: a drilled hole, an earlier pass, outside the blank). Tooth k cuts when (i) it faces
//!   the feed (`cos(alpha) = r_k . u > 0`, so entry and exit angles come from the geometry);
//!   (ii) its line (lateral offset `y = R sin(alpha)` of the edge from the path, at most half a
//!   cell inside the swath's side, so a line never runs in the row of cells just beyond the
//!   swath, never cut) has material at the probe `P`, one cell beyond the envelope of the discs
//!   swept along a straight path along the envelope's normal (`x_env = sqrt(R^2 - y^2)` ahead of
//!   the axis, `P` at `x_env + m`, `m = min(cell R / x_env, 8 cell)`); the axial depth is
//!   `a = top(P) - base`; (iii) walking back from `P` along the line to `back = max(c, 2 m)`
//!   behind the envelope, no old air lies between `P` and the envelope (a gap the tool has not
//!   crossed: coming back along its own slot, or the far wall of a hole of its own size just
//!   ahead), and some cell on the way is air the tool made recently (the tool is taking
//!   material on this line, not only touching a cell whose square reaches into its disc: the
//!   grid knows material at cell centres only). Its chip's length along the feed is then
//!   `min(c, extent)`, `extent` the distance from the envelope back to the first old air (the
//!   material behind the edge: entering a wall, the tool's penetration; unlimited when there is
//!   none within `back`): chip `h = min(c, extent) cos(alpha)` (the paper's `c sin(phi)` with
//!   phi measured from the entry side); `Ft = Ks(h) a h`, `Fr = Kr Ft` (`Ks(h)` =
//!   [`Material::ks_at`]: constant unless the material has a size-effect exponent). The recent
//!   path is `L = back + 2 cell + sqrt(R^2 - (|y| - cell / sqrt(2))^2) - x_env`: how far back
//!   along the path a cell on the line within `back` of the envelope can have been lowered (near
//!   the tool's sides the disc reaches a cell well before the edge passes it). Resolution: the
//!   grid's. Along a wall the engaged edge angles are the textbook's (`acos(1 - 2 ae / D)`) for a
//!   wall on a cell boundary, within half a cell of radial depth otherwise; entering a wall, a
//!   tooth starts cutting once the tool has covered a material cell centre on its line (half a
//!   cell past the wall at the front, about `cell / 2 (1 + tan |alpha|)` towards the sides); a
//!   gap ahead is seen, except one narrower than a cell left by the tool's own swath within `L`
//!   of path (a reversal within about a cell and a feed per tooth of where it turned). When the
//!   motion stops, `c` falls to zero over one tooth period (a real tool also cuts its last,
//!   thinning chips).
//! - End face (plunges and ramps; a simple mechanistic model of our own, the thesis has none):
//!   when the tip moved down over the window (`c_z > 0`), each end tooth k (center cutting: an
//!   edge from the axis to R at the angle `psi_k`) cuts a chip of thickness `c_z` over its engaged
//!   radial width `w_k`: the length along its edge where the stock has material above the tip
//!   (sampled at cell spacing, only cells whose centre is within R of the axis, the cells the
//!   removal cuts; material below the blank's floor does not count). `Ft_k = Ks(c_z) c_z w_k`
//!   against the cutting speed, acting over the edge, so its torque is `Ks(c_z) c_z sum(r dr)`
//!   (= `Ft_k r_mean`, r_mean = R / 2 for a full-width edge); axial force `Fa = Ka sum Ft_k`
//!   (up on the tool; [`Material`]'s `ka`); no radial component. The tangential forces of
//!   symmetric teeth cancel in a full plunge (F = 0: the plunge loads the spindle, T, and the
//!   axis, Fa); a partly engaged end face (the rim of a hole) leaves a net radial force. A ramp
//!   gets both the side and the end contributions. The material above the tip is read with a
//!   1e-6 mm tolerance (a tip landing on a prepared floor of the same nominal height cuts
//!   nothing), and when the tip did not step down since the previous sample (a slow plunge
//!   between two Z steps), material at the tip's height counts if the end face cut at the
//!   previous sample (the removal has just lowered it to the tip: it is the layer the next tooth
//!   meets). Fa is the plant's truth only: the transducer measures T, Fu, Fv (the paper's), so a
//!   controller sees a plunge through its torque.
//! - Force on the tool: `Ft` against the cutting speed, `Fr` towards the axis; X/Y resultant
//!   summed over the teeth; torque `T = R sum Ft`. `Fu`, `Fv`: the resultant in the holder frame
//!   rotating with the spindle (`u` axis at world angle `-theta`, `v` 90 degrees
//!   counter-clockwise from it), so `F = sqrt(Fu^2 + Fv^2)` is invariant.
//! - Run-out and damaged teeth ([`crate::teeth`]): each tooth's chip `h_k` replaces `c cos(alpha)`
//!   (and its end chip `c_z`) as that module describes, at most `extent cos(alpha)`; the intact
//!   tool without run-out keeps the arithmetic above.
//! - Removal after the force: cells within R of the segment from the previous sample's position
//!   to this one get `top = min(top, tip Z)`.
use std::collections::VecDeque;

use crate::drive::{Drive, DriveModel};
use crate::stock::Cell;
use crate::teeth::{Damage, Teeth, ToothEvent};
use crate::{validate, CutError, Material, Shape, Stock, Tool, Transducer, MM_PER_BLU};

/// Tolerance of the end face's "material above the tip" test, mm (see the module docs).
const END_EPS_MM: f64 = 1e-6;

/// One ADC sample of the process.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// True resultant radial force on the cutter, N.
    pub f_true_n: f64,
    /// True cutting torque, N*m (positive = load on the spindle).
    pub t_true_nm: f64,
    /// Force components in the rotating holder frame, N (`f_true_n = hypot(fu_n, fv_n)`).
    pub fu_n: f64,
    pub fv_n: f64,
    /// True axial force of the end teeth, N (positive = pushing the tool up); not measured by the
    /// transducer.
    pub fa_n: f64,
    /// 12-bit ADC codes [T, Fu, Fv] with noise.
    pub codes: [u16; 3],
}

/// The end-face chip at one instant: feed per tooth along -Z (mm, 0 = no end cut) and the height
/// above which the stock's material engages the end teeth (mm; see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EndCut {
    pub cz: f64,
    pub z_min: f64,
}

impl EndCut {
    pub const NONE: EndCut = EndCut {
        cz: 0.0,
        z_min: f64::INFINITY,
    };

    /// The end cut of a tip at `z` moving down `cz` per tooth: material strictly above the tip,
    /// or (`hold`) at its height too.
    pub fn new(cz: f64, z: f64, hold: bool) -> EndCut {
        EndCut {
            cz,
            z_min: if hold { z - END_EPS_MM } else { z + END_EPS_MM },
        }
    }
}

/// Forces on the tool at one instant: (Fx, Fy) N in XY, torque N*m, axial force N, whether
/// an end tooth met material, and whether some side tooth's chip was limited by the material
/// behind its edge (its extent shorter than the reach: the force is not linear in the feed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Forces {
    pub fx: f64,
    pub fy: f64,
    pub t: f64,
    pub fa: f64,
    pub end_engaged: bool,
    pub capped: bool,
}

/// A side tooth in the cut (see [`Cutter::side_tooth`]): its world angle's sine and cosine,
/// `cos(alpha)` (the chip per mm of feed), the axial depth `a` (mm) and the extent of the
/// material behind its edge along the feed (mm; infinite: at least the reach), which limits the
/// feed per tooth it sees; the edge's radius `r` (mm: the torque's lever) and the sine and cosine
/// of the angle `kappa` between the tool's axis and the edge's normal (a flat end mill's side:
/// 1 and 0; a ball's slice: its place on the sphere, see [`Slice`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SideTooth {
    pub sin: f64,
    pub cos: f64,
    pub cos_a: f64,
    pub a: f64,
    pub extent: f64,
    pub r: f64,
    pub sin_k: f64,
    pub cos_k: f64,
}

/// Side slices of a ball end mill's hemisphere (the cylinder above it is one more).
pub(crate) const BALL_SLICES: u32 = 8;

/// One axial slice of a side tooth's edge: its radius `r` (mm), the height of its bottom above
/// the tip `z_lo` (mm), the most depth it engages `a_max` (mm; infinite: all the material above
/// it) and the sine and cosine of `kappa`, the angle between the tool's axis and the edge's
/// normal there (the local chip is `c cos(alpha) sin(kappa)`). A flat end mill has one slice:
/// its whole side. A ball end mill has [`BALL_SLICES`] equal slices of height `R / n` up the
/// hemisphere (each at the radius and angle of its middle) and the cylinder above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Slice {
    pub r: f64,
    /// The radius at the slice's top, where its edge reaches furthest: the line it meets
    /// material on ([`Cutter::side_tooth`]; the rest of the slice's edge meets what lies above
    /// the sphere's surface at that radius, cut down to it by the removal).
    pub r_probe: f64,
    pub z_lo: f64,
    pub a_max: f64,
    pub sin_k: f64,
    pub cos_k: f64,
}

/// An end tooth against the material (see [`Cutter::forces`]): its world angle's sine and
/// cosine, its engaged radial width `w` (mm) and `sum(r dr)` over it (mm^2).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct EndTooth {
    pub sin: f64,
    pub cos: f64,
    pub w: f64,
    pub moment: f64,
}

/// One tooth's contacts with the stock at one instant ([`Cutter::contacts`]): its side chip's
/// geometry (None: the side tooth cuts nothing) and its end face's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Contact {
    pub side: Option<SideTooth>,
    pub end: EndTooth,
}

/// Geometry and model constants shared by the process and the oracle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cutter {
    pub r_mm: f64,
    pub flutes: u32,
    pub material: Material,
    /// Probe margin (one cell), see the module docs.
    pub probe_mm: f64,
    pub shape: Shape,
    /// Slices per side tooth ([`Slice`]): the contacts per tooth.
    pub slices: u32,
}

impl Cutter {
    pub fn new(tool: &Tool, material: &Material, stock: &Stock) -> Cutter {
        Cutter {
            r_mm: tool.diameter_mm / 2.0,
            flutes: tool.flutes,
            material: *material,
            probe_mm: stock.cell_mm(),
            shape: tool.shape,
            slices: match tool.shape {
                Shape::Ball => BALL_SLICES + 1,
                Shape::Flat | Shape::Drill { .. } => 1,
            },
        }
    }

    /// The contacts of all the teeth: `flutes` x `slices`, tooth k's slices at
    /// `k * slices ..`.
    pub fn edges(&self) -> usize {
        (self.flutes * self.slices) as usize
    }

    /// Slice `j` of a side tooth ([`Slice`]).
    #[inline]
    pub fn slice(&self, j: u32) -> Slice {
        let r = self.r_mm;
        match self.shape {
            Shape::Ball if j < BALL_SLICES => {
                let dz = r / f64::from(BALL_SLICES);
                let z_lo = f64::from(j) * dz;
                let zm = z_lo + 0.5 * dz;
                let rj = (zm * (2.0 * r - zm)).sqrt();
                let z_hi = z_lo + dz;
                Slice {
                    r: rj,
                    r_probe: (z_hi * (2.0 * r - z_hi)).max(0.0).sqrt().min(r),
                    z_lo,
                    a_max: dz,
                    sin_k: rj / r,
                    cos_k: (r - zm) / r,
                }
            }
            Shape::Ball => Slice {
                r,
                r_probe: r,
                z_lo: r,
                a_max: f64::INFINITY,
                sin_k: 1.0,
                cos_k: 0.0,
            },
            Shape::Flat | Shape::Drill { .. } => Slice {
                r,
                r_probe: r,
                z_lo: 0.0,
                a_max: f64::INFINITY,
                sin_k: 1.0,
                cos_k: 0.0,
            },
        }
    }

    /// Side contact `e` (tooth `e / slices`, its slice `e % slices`) at world angle `psi`: see
    /// [`Cutter::side_tooth`]. A drill has none.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn side_edge(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        psi: f64,
        e: u32,
        u: [f64; 2],
        reach: f64,
        top_bound: f64,
    ) -> Option<SideTooth> {
        if matches!(self.shape, Shape::Drill { .. }) {
            return None;
        }
        let sl = self.slice(e % self.slices);
        self.side_tooth_below(stock, tip, psi, u, reach, top_bound, &sl)
    }

    /// Where side tooth `psi` (world angle, rad) of the tool with its tip at `tip` (mm), moving
    /// along `u` (unit, XY), meets material, and how much of it lies behind its edge: None when
    /// the tooth faces away from the feed or cuts nothing (see the module docs). `reach`: the
    /// longest feed per tooth (mm, XY) the extent is measured for (the process: its `c`).
    #[cfg(test)]
    #[inline]
    pub fn side_tooth(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        psi: f64,
        u: [f64; 2],
        reach: f64,
    ) -> Option<SideTooth> {
        let sl = self.slice(0);
        self.side_tooth_below(stock, tip, psi, u, reach, stock.max_top(), &sl)
    }

    /// [`Cutter::side_tooth`] of slice `sl` where no cell within `r_mm` + 9 cells of the tip
    /// has its top above `top_bound` (mm): the stock's highest top, or a bound near the tool.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn side_tooth_below(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        psi: f64,
        u: [f64; 2],
        reach: f64,
        top_bound: f64,
        sl: &Slice,
    ) -> Option<SideTooth> {
        let cell = self.probe_mm;
        let r_mm = sl.r_probe;
        // A slice thinner than a cell's half has no line of its own on the grid.
        if r_mm <= 0.5 * cell {
            return None;
        }
        // (A flat end mill's one slice: the tip itself, the same bytes as ever.)
        let bottom = if sl.z_lo == 0.0 {
            tip[2]
        } else {
            tip[2] + sl.z_lo
        };
        let base = bottom.max(stock.floor_mm());
        // Above the highest top near the tool no material is ahead of any tooth (the probe
        // below, within `r_mm` + 8 cells of the tip, would find `a <= 0`): the same answer
        // without the angle's sine and cosine.
        if base >= top_bound {
            return None;
        }
        let (s, co) = psi.sin_cos();
        let cos_a = co * u[0] + s * u[1];
        if cos_a <= 0.0 {
            return None;
        }
        // The line along the feed through the edge (y: its lateral offset from the path, at most
        // half a cell inside the swath's side), the envelope of the swept discs on it at `x_env`
        // ahead of the axis, the probe one cell beyond the envelope along its normal.
        let y_max = r_mm - 0.5 * cell;
        let y = (r_mm * (co * u[1] - s * u[0])).clamp(-y_max, y_max);
        let x_env = (r_mm * r_mm - y * y).sqrt();
        let margin = (cell * r_mm / x_env).min(8.0 * cell);
        let ahead = x_env + margin;
        let px = tip[0] + y * u[1] + ahead * u[0];
        let py = tip[1] - y * u[0] + ahead * u[1];
        let a = (stock.top_at(px, py) - base).min(sl.a_max);
        if a <= 0.0 {
            return None;
        }
        // What is material for this edge: above the slice's bottom for the flat end mill's one
        // slice; a ball's slice has cut the cells it passed down to the sphere's surface, at
        // most the top of what it engages (the probe's cell, just beyond its reach, is
        // material).
        let class_z = if sl.a_max.is_finite() {
            base + a - 1e-6
        } else {
            base
        };
        // Back from the probe along the line to one feed per tooth (at least one cell) behind
        // the envelope: no old air before the envelope, some air the tool made recently, and
        // the extent of what is not old air behind the envelope.
        let back = reach.max(2.0 * margin);
        let hd = cell * std::f64::consts::FRAC_1_SQRT_2;
        let side = (r_mm * r_mm - (y.abs() - hd).max(0.0).powi(2)).sqrt() - x_env;
        let recent = stock.odometer_mm() - (back + 2.0 * cell + side);
        let (mut made, mut extent) = (false, f64::INFINITY);
        stock.walk([px, py], [-u[0], -u[1]], margin + back, |t, k| match stock
            .cell_class(k, class_z, recent)
        {
            Cell::Material => true,
            Cell::Recent => {
                made = true;
                true
            }
            Cell::Old => {
                extent = t - margin;
                false
            }
        });
        if !made || extent <= 0.0 {
            return None;
        }
        Some(SideTooth {
            sin: s,
            cos: co,
            cos_a,
            a,
            extent: if extent >= reach {
                f64::INFINITY
            } else {
                extent
            },
            r: sl.r,
            sin_k: sl.sin_k,
            cos_k: sl.cos_k,
        })
    }

    /// End tooth `psi` (world angle, rad) of the tool with its tip at `tip` (mm) against the
    /// material above `z_min` (mm; [`EndCut`]): its world angle's sine and cosine, its engaged
    /// radial width `w` (mm) and `sum(r dr)` (mm^2) over it (see the module docs).
    #[inline]
    fn end_tooth(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        psi: f64,
        z_min: f64,
        top_bound: f64,
    ) -> EndTooth {
        if self.shape == Shape::Flat {
            return self.end_tooth_by(tip, psi, z_min, top_bound, |x, y| {
                stock.top_in_disc(x, y, tip[0], tip[1], self.r_mm) > z_min
            });
        }
        // A ball's or a drill's end edge meets the cell holding (x, y) where the cell's top is
        // above the edge's surface over the cell's centre (the height the removal cut it to).
        self.end_tooth_by(tip, psi, z_min, top_bound, |x, y| {
            let (top, d2) = stock.top_d2_in_disc(x, y, tip[0], tip[1], self.r_mm);
            top > z_min + self.shape.lift_mm(self.r_mm, d2.sqrt())
        })
    }

    /// [`Cutter::end_tooth`] with `above(x, y)`: the cell holding (x, y) under the disc is above
    /// the end face (for a flat end mill: `z_min`; a ball's or a drill's edge: see
    /// [`Cutter::end_tooth`]).
    #[inline(always)]
    fn end_tooth_by(
        &self,
        tip: [f64; 3],
        psi: f64,
        z_min: f64,
        top_bound: f64,
        above: impl Fn(f64, f64) -> bool,
    ) -> EndTooth {
        // Each end tooth's edge sampled at (about) cell spacing from the axis to the rim.
        let n = (self.r_mm / self.probe_mm).ceil().max(1.0);
        let dr = self.r_mm / n;
        let (s, co) = psi.sin_cos();
        let (mut w, mut moment) = (0.0, 0.0);
        // Above the highest top under the tool (`top_bound`: the stock's, or a bound near the
        // tool) no cell is above `z_min`: nothing engaged, without the walk.
        let edge = if z_min >= top_bound { 0 } else { n as usize };
        for j in 0..edge {
            let r = (j as f64 + 0.5) * dr;
            if above(tip[0] + r * co, tip[1] + r * s) {
                w += dr;
                moment += r * dr;
            }
        }
        EndTooth {
            sin: s,
            cos: co,
            w,
            moment,
        }
    }

    /// Forces of all teeth at spindle angle `theta` (rad, clockwise), tool tip at `tip` (mm),
    /// unit feed direction `u` (XY; [0, 0] when the tool does not move in XY), feed per tooth
    /// `c` (mm, XY), the side chip's extent measured up to `reach` (mm, >= the feeds per tooth
    /// the result is used for; the process: `c`) and the end-face chip `end`. `teeth`: the
    /// teeth's radius offsets (mm, -inf = broken; [`crate::teeth`]), None for the intact tool
    /// without run-out. `wave`: the flexible tool's deflection now minus one tooth period ago
    /// (mm, XY; [`Process::with_tool_modes`]), added to every side chip along the tooth's radial
    /// direction (the regenerative chip); None for a rigid tool.
    #[allow(clippy::too_many_arguments)]
    pub fn forces(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        theta: f64,
        u: [f64; 2],
        c: f64,
        reach: f64,
        end: EndCut,
        teeth: Option<&[f64]>,
        wave: Option<[f64; 2]>,
    ) -> Forces {
        let pitch = std::f64::consts::TAU / self.flutes as f64;
        let psi = |k: u32| -theta - k as f64 * pitch;
        let top = stock.max_top();
        self.sum_forces(
            c,
            end,
            end.cz > 0.0 && tip[2] >= stock.floor_mm(),
            teeth,
            wave,
            |e| self.side_edge(stock, tip, psi(e / self.slices), e, u, reach, top),
            |k| self.end_tooth(stock, tip, psi(k), end.z_min, top),
        )
    }

    /// The teeth's contacts with `stock` at spindle angle `theta` (rad), the tool tip at `tip`
    /// (mm) moving along `u` (unit, XY), the side chip's extent measured up to `reach` (mm) and
    /// the end teeth against the material above `z_min` (mm; None: no end cut), one per tooth
    /// and slice into `out` ([`Cutter::edges`] long; a tooth's end face in its first slice's):
    /// what [`Cutter::forces`] reads of the stock, which does not
    /// depend on the feed. [`Cutter::forces_of`] sums them at a feed (the oracle's searches).
    /// Returns whether the end face can cut (the tip not below the blank's floor). `top_bound`:
    /// no cell near the tool ([`Cutter::near_top`]) has its top above it (the stock's highest
    /// top will do); the same contacts, read faster where the tool is clear of the material.
    #[allow(clippy::too_many_arguments)]
    pub fn contacts(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        theta: f64,
        u: [f64; 2],
        reach: f64,
        z_min: Option<f64>,
        top_bound: f64,
        mask: Option<&crate::stock::DiscMask>,
        out: &mut [Contact],
    ) -> bool {
        let pitch = std::f64::consts::TAU / self.flutes as f64;
        let end_ok = z_min.is_some() && tip[2] >= stock.floor_mm();
        // A mask answers for one height: a flat end face's.
        let mask = mask.filter(|_| self.shape == Shape::Flat);
        for (e, slot) in out.iter_mut().enumerate().take(self.edges()) {
            let e = e as u32;
            let psi = -theta - (e / self.slices) as f64 * pitch;
            *slot = Contact {
                side: self.side_edge(stock, tip, psi, e, u, reach, top_bound),
                end: match z_min {
                    // A tooth's end face: its first slice's contact holds it.
                    Some(z) if end_ok && e % self.slices == 0 => match mask {
                        Some(m) => self.end_tooth_by(tip, psi, z, top_bound, |x, y| {
                            stock.above_in_disc(m, x, y)
                        }),
                        None => self.end_tooth(stock, tip, psi, z, top_bound),
                    },
                    _ => EndTooth::default(),
                },
            };
        }
        end_ok
    }

    /// The highest top of the cells a tooth of the tool with its tip at `tip` can read (a side
    /// tooth's probe lies within `r_mm` + 8 cells of the axis, an end tooth's edge within
    /// `r_mm`): a `top_bound` for [`Cutter::contacts`].
    pub fn near_top(&self, stock: &Stock, tip: [f64; 3]) -> f64 {
        stock.max_top_near(tip[0], tip[1], self.r_mm + 9.0 * self.probe_mm)
    }

    /// [`Cutter::forces`] from the teeth's `contacts` ([`Cutter::contacts`], made with the same
    /// tip, angle, direction and reach, and `end`'s `z_min` when `end.cz > 0`; `end_ok` its
    /// answer): the same bytes.
    pub fn forces_of(
        &self,
        contacts: &[Contact],
        end_ok: bool,
        c: f64,
        end: EndCut,
        teeth: Option<&[f64]>,
        wave: Option<[f64; 2]>,
    ) -> Forces {
        self.sum_forces(
            c,
            end,
            end.cz > 0.0 && end_ok,
            teeth,
            wave,
            |e| contacts[e as usize].side,
            |k| contacts[(k * self.slices) as usize].end,
        )
    }

    /// The forces' sum over the teeth (see [`Cutter::forces`]), tooth k's side contact from
    /// `side(k)` (asked only while `c > 0`) and, when `end_on`, its end contact from `end_at(k)`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sum_forces(
        &self,
        c: f64,
        end: EndCut,
        end_on: bool,
        teeth: Option<&[f64]>,
        wave: Option<[f64; 2]>,
        mut side: impl FnMut(u32) -> Option<SideTooth>,
        mut end_at: impl FnMut(u32) -> EndTooth,
    ) -> Forces {
        let mut f = Forces::default();
        let m = &self.material;
        let z = self.flutes as usize;
        for e in 0..self.flutes * self.slices {
            if c <= 0.0 {
                break;
            }
            let Some(st) = side(e) else {
                continue;
            };
            let k = e / self.slices;
            f.capped |= st.extent.is_finite();
            let (s, co) = (st.sin, st.cos);
            // The chip: the feed per tooth, limited by the material behind the edge (also the
            // chip a damaged tooth leaves to the next one).
            let cap = st.extent * st.cos_a;
            let cc = (c * st.cos_a).min(cap);
            let mut h =
                teeth.map(|d| crate::teeth::chip_mm(k as usize, z, c * st.cos_a, d).min(cap));
            if let Some(w) = wave {
                let h0 = h.unwrap_or(cc);
                h = Some(if h0 > 0.0 {
                    h0 + w[0] * co + w[1] * s
                } else {
                    0.0
                });
            }
            if h.is_some_and(|h| h <= 0.0) {
                continue;
            }
            let a = st.a;
            // A slice of a ball: the chip normal to the edge is `h sin(kappa)` over an edge
            // `a / sin(kappa)` long, so Ft = Ks(h sin(kappa)) a h; the normal force Kr Ft
            // pushes the tool towards its axis by sin(kappa) and up by cos(kappa). A flat end
            // mill's side (sin 1, cos 0): Ks(h) a h towards the axis, the same bytes.
            let ks = |h: f64| {
                if st.sin_k == 1.0 {
                    m.ks_at(h)
                } else {
                    m.ks_at(h * st.sin_k)
                }
            };
            let ft = match h {
                None => ks(cc) * a * cc,
                Some(h) => ks(h) * a * h,
            };
            let fr = m.kr * ft;
            let fr_xy = if st.sin_k == 1.0 { fr } else { fr * st.sin_k };
            f.fx += -ft * s - fr_xy * co;
            f.fy += ft * co - fr_xy * s;
            f.t += ft * st.r / 1000.0;
            if st.cos_k != 0.0 {
                f.fa += fr * st.cos_k;
            }
        }
        if end_on {
            let ks = m.ks_at(end.cz);
            for k in 0..self.flutes {
                // A broken end tooth cuts nothing; the next intact one takes its share.
                let (cz, ks) = match teeth.map(|d| crate::teeth::end_share(k as usize, z, d)) {
                    None => (end.cz, ks),
                    Some(0.0) => continue,
                    Some(n) => (n * end.cz, m.ks_at(n * end.cz)),
                };
                let EndTooth {
                    sin: s,
                    cos: co,
                    w,
                    moment,
                } = end_at(k);
                if w > 0.0 {
                    let ft = ks * cz * w;
                    f.fx += -ft * s;
                    f.fy += ft * co;
                    f.t += ks * cz * moment / 1000.0;
                    f.fa += m.ka * ft;
                    f.end_engaged = true;
                }
            }
        }
        f
    }
}

/// The simulated cutting process (stock, tool, material, spindle, transducer, noise).
#[derive(Clone, Debug)]
pub struct Process {
    stock: Stock,
    tool: Tool,
    material: Material,
    rpm: f64,
    transducer: Transducer,
    cutter: Cutter,
    rng: crate::rng::SplitMix64,
    /// (t, tip position mm) of the samples of the last tooth period and one before it.
    hist: VecDeque<(f64, [f64; 3])>,
    /// The feed drives: the commanded position (pulses) to where the tool is.
    drive_model: DriveModel,
    drive: Option<Drive>,
    /// Whether the end face met material at the previous sample (see the module docs).
    end_engaged: bool,
    /// The teeth's run-out and damage ([`crate::teeth`]).
    teeth: Teeth,
    /// The flexible tool and its microphone (None: a rigid tool, no sound).
    flex: Option<Flex>,
}

/// A flexible tool in the process ([`Process::with_tool_modes`]): its modes in X and Y, the
/// deflections of the last tooth period at the fine step, and the microphone.
#[derive(Clone, Debug)]
struct Flex {
    x: crate::chatter::Axis,
    y: crate::chatter::Axis,
    /// The highest natural frequency, Hz (sets the fine step).
    f_max_hz: f64,
    /// Deflections (mm) of the last tooth period, the oldest at `at`; the fine step divides the
    /// tooth period into `ring.len()` steps.
    ring: Vec<[f64; 2]>,
    at: usize,
    dt: f64,
    /// The fine time (s): the dynamics have been integrated up to here.
    t: f64,
    /// The tooth period the ring was made for, s.
    tooth_s: f64,
    listener: crate::chatter::Listener,
    /// The microphone's codes not yet taken, oldest first.
    sound: VecDeque<u16>,
    /// The microphone's code of silence (its offset), to pad a short block.
    silence: u16,
}

impl Flex {
    /// A ring for tooth period `tooth_s` at 40 steps per period of the fastest mode.
    fn size_for(&mut self, tooth_s: f64) {
        let steps = ((tooth_s * self.f_max_hz * 40.0).ceil() as usize).max(16);
        self.ring = vec![[0.0; 2]; steps];
        self.at = 0;
        self.dt = tooth_s / steps as f64;
        self.tooth_s = tooth_s;
    }

    fn deflection_mm(&self) -> [f64; 2] {
        [self.x.displacement() * 1e3, self.y.displacement() * 1e3]
    }
}

impl Process {
    /// A process on `stock` with `tool` in `material` at `spindle_rpm`; `seed` seeds the noise.
    pub fn new(
        stock: Stock,
        tool: Tool,
        material: Material,
        spindle_rpm: f64,
        seed: u64,
        transducer: Transducer,
    ) -> Result<Process, CutError> {
        validate(&tool, &material, spindle_rpm)?;
        let t_ok = transducer.gain.iter().all(|g| g.is_finite() && *g != 0.0)
            && transducer.offset.iter().all(|o| (0.0..=4095.0).contains(o))
            && transducer.noise_sigma_codes.is_finite()
            && transducer.noise_sigma_codes >= 0.0;
        if !t_ok {
            return Err(CutError(
                "transducer gains must be finite and non-zero, offsets 0..=4095, sigma >= 0".into(),
            ));
        }
        let cutter = Cutter::new(&tool, &material, &stock);
        Ok(Process {
            stock,
            tool,
            material,
            rpm: spindle_rpm,
            transducer,
            cutter,
            rng: crate::rng::SplitMix64::new(seed),
            hist: VecDeque::new(),
            drive_model: DriveModel::Stepper,
            drive: None,
            end_engaged: false,
            flex: None,
            teeth: Teeth::default(),
        })
    }

    /// The process behind feed drives of `model` (the default: a stepper, the tool where the
    /// pulses put it). The drive starts at rest at the first sample's commanded position.
    pub fn with_drive(mut self, model: DriveModel) -> Self {
        self.drive_model = model;
        self.drive = None;
        self
    }

    /// The process with tooth k's radial run-out `runout_mm[k]` (mm, one value per tooth, signed,
    /// finite, within +-[`crate::teeth::MAX_RUNOUT_MM`]; see [`crate::teeth`]).
    pub fn with_runout(mut self, runout_mm: &[f64]) -> Result<Self, CutError> {
        self.teeth.set_runout(self.tool.flutes, runout_mm)?;
        Ok(self)
    }

    /// The process with tooth `tooth` (from 0) broken from virtual time `t_s` on: it cuts nothing,
    /// the next tooth takes its chip ([`crate::teeth`]).
    pub fn break_tooth(self, tooth: u32, t_s: f64) -> Result<Self, CutError> {
        self.with_tooth_event(ToothEvent {
            tooth,
            t_s,
            damage: Damage::Broken,
        })
    }

    /// The process with tooth `tooth` (from 0) chipped from virtual time `t_s` on: its edge loses
    /// `depth_mm` of radius (finite, >= 0; [`crate::teeth::DEFAULT_CHIP_MM`] is the CLI's
    /// default).
    pub fn chip_tooth(self, tooth: u32, t_s: f64, depth_mm: f64) -> Result<Self, CutError> {
        self.with_tooth_event(ToothEvent {
            tooth,
            t_s,
            damage: Damage::Chipped { depth_mm },
        })
    }

    /// The process with a tooth's damage `event` (checked against the tool's flutes).
    pub fn with_tooth_event(mut self, event: ToothEvent) -> Result<Self, CutError> {
        self.teeth.add(self.tool.flutes, event)?;
        Ok(self)
    }

    /// The teeth's run-out and damage.
    pub fn teeth(&self) -> &Teeth {
        &self.teeth
    }

    /// The tool flexible in X and Y with `x` and `y` modes (issue 10; [`crate::chatter`]'s model
    /// inside the process): between ADC samples the deflection is integrated at a fine step (40
    /// per period of the fastest mode, a whole number per tooth period), every side chip gets the
    /// regenerative term (the deflection now minus one tooth period ago, along the tooth's
    /// radius), the forces at the sample are those of the deflected tool, the stock is cut where
    /// the deflected tool is, and `mic` hears the tool's vibration at `sound_hz`
    /// ([`Process::take_sound`]). Without it the tool is rigid (the default, the same bytes).
    pub fn with_tool_modes(
        mut self,
        x: &[crate::lobes::Mode],
        y: &[crate::lobes::Mode],
        mic: crate::chatter::Microphone,
        sound_hz: f64,
        seed: u64,
    ) -> Result<Self, CutError> {
        let ok = |m: &crate::lobes::Mode| {
            m.fn_hz.is_finite()
                && m.fn_hz > 0.0
                && m.fn_hz <= 50_000.0
                && m.zeta.is_finite()
                && m.zeta > 0.0
                && m.zeta < 1.0
                && m.k_n_m.is_finite()
                && m.k_n_m > 0.0
        };
        if !(x.iter().chain(y.iter()).all(ok) && !(x.is_empty() && y.is_empty())) {
            return Err(CutError(
                "tool modes: at least one; frequency in (0, 50000] Hz, damping in (0, 1), \
                 stiffness > 0"
                    .into(),
            ));
        }
        if !(sound_hz.is_finite() && (1000.0..=200_000.0).contains(&sound_hz)) {
            return Err(CutError(format!(
                "sound sample rate must be 1000..=200000 Hz, got {sound_hz}"
            )));
        }
        let f_max_hz = x
            .iter()
            .chain(y.iter())
            .map(|m| m.fn_hz)
            .fold(0.0, f64::max);
        let mut flex = Flex {
            x: crate::chatter::Axis::new(x),
            y: crate::chatter::Axis::new(y),
            f_max_hz,
            ring: Vec::new(),
            at: 0,
            dt: 0.0,
            t: 0.0,
            tooth_s: 0.0,
            listener: crate::chatter::Listener::new(mic, sound_hz, seed),
            sound: VecDeque::new(),
            silence: mic.offset.round().clamp(0.0, 4095.0) as u16,
        };
        flex.size_for(60.0 / (self.rpm * self.cutter.flutes as f64));
        self.flex = Some(flex);
        Ok(self)
    }

    /// The microphone's codes since the last call (empty for a rigid tool).
    pub fn take_sound(&mut self) -> Vec<u16> {
        self.flex
            .as_mut()
            .map(|f| f.sound.drain(..).collect())
            .unwrap_or_default()
    }

    /// The next `N` microphone codes, oldest first, for an ADC that delivers exactly `N` per
    /// sample (the sound rate `N` times the sample rate): short of codes (the fine step's rounding
    /// may leave one for the next sample), the block is padded with silence. None for a rigid
    /// tool (no microphone).
    pub fn take_sound_block<const N: usize>(&mut self) -> Option<[u16; N]> {
        let flex = self.flex.as_mut()?;
        let mut out = [flex.silence; N];
        for slot in out.iter_mut() {
            match flex.sound.pop_front() {
                Some(c) => *slot = c,
                None => break,
            }
        }
        Some(out)
    }

    /// The spindle now turns at `rpm` (from the next sample on): a program's S in a session
    /// whose program arrives as it runs. Refused outside (0, 100000] rpm, the speed unchanged.
    pub fn set_spindle_rpm(&mut self, rpm: f64) -> Result<(), CutError> {
        crate::validate_rpm(rpm)?;
        self.rpm = rpm;
        Ok(())
    }

    /// A tool change: `tool` cuts from the next sample on, at `rpm`, the stock as the tool before
    /// left it. What belonged to the old tool goes with it: its teeth's run-out and damage, its
    /// modes (the new tool is rigid), the feed history of its last tooth period. Refused (nothing
    /// changed) for a tool or speed [`Process::new`] would refuse.
    pub fn change_tool(&mut self, tool: Tool, rpm: f64) -> Result<(), CutError> {
        crate::validate(&tool, &self.material, rpm)?;
        self.cutter = Cutter::new(&tool, &self.material, &self.stock);
        self.tool = tool;
        self.rpm = rpm;
        self.teeth = Teeth::default();
        self.flex = None;
        self.hist.clear();
        self.end_engaged = false;
        Ok(())
    }

    /// The spindle speed, rpm.
    pub fn spindle_rpm(&self) -> f64 {
        self.rpm
    }

    /// The stock as cut so far.
    pub fn stock(&self) -> &Stock {
        &self.stock
    }

    /// The stock as cut so far, consuming the process (to cut it again with another process).
    pub fn into_stock(self) -> Stock {
        self.stock
    }

    /// The cutter's geometry and model (the tests' view of the chip).
    #[cfg(test)]
    pub(crate) fn cutter(&self) -> &Cutter {
        &self.cutter
    }

    pub fn tool(&self) -> &Tool {
        &self.tool
    }

    /// One ADC sample at time `t_s` (s, non-decreasing between calls) with the tool commanded to
    /// `pos_blu` ([X, Y, Z] in BLU, machine coordinates = stock coordinates; the drive model
    /// gives where the tip really is).
    pub fn sample(&mut self, t_s: f64, pos_blu: [i64; 3]) -> Sample {
        let model = self.drive_model;
        let drive = self.drive.get_or_insert_with(|| Drive::new(model, pos_blu));
        let p = drive.follow(t_s, pos_blu).map(|v| v * MM_PER_BLU);
        if let Some(&(t_last, _)) = self.hist.back() {
            assert!(t_s >= t_last, "Process::sample called out of time order");
        }
        let prev = self.hist.back().map(|&(_, q)| q);
        self.hist.push_back((t_s, p));
        let z = self.cutter.flutes as f64;
        let tooth_period = 60.0 / (self.rpm * z);
        while self.hist.len() >= 2 && self.hist[1].0 <= t_s - tooth_period {
            self.hist.pop_front();
        }
        let (t_old, q) = self.hist[0];
        let (dx, dy) = (p[0] - q[0], p[1] - q[1]);
        let dxy = dx.hypot(dy);
        let dt = t_s - t_old;
        let theta = std::f64::consts::TAU * self.rpm * t_s / 60.0;
        let cz = if dt > 0.0 {
            (q[2] - p[2]).max(0.0) / (z * self.rpm / 60.0 * dt)
        } else {
            0.0
        };
        let f = if dt > 0.0 && (dxy > 0.0 || cz > 0.0) {
            let (c, u) = if dxy > 0.0 {
                (dxy / (z * self.rpm / 60.0 * dt), [dx / dxy, dy / dxy])
            } else {
                (0.0, [0.0; 2])
            };
            let hold = self.end_engaged && prev.is_some_and(|a| a[2] == p[2]);
            let end = EndCut::new(cz, p[2], hold);
            let mut d = [0.0; crate::teeth::HISTORY_LEN];
            let n = self
                .teeth
                .history(self.cutter.flutes, t_s, tooth_period, &mut d);
            let teeth = (n > 0).then_some(&d[..n]);
            match self.flex.as_mut() {
                None => self
                    .cutter
                    .forces(&self.stock, p, theta, u, c, c, end, teeth, None),
                Some(flex) => flex_to(
                    flex,
                    &self.cutter,
                    &self.stock,
                    t_s,
                    self.rpm,
                    p,
                    u,
                    c,
                    end,
                    teeth,
                ),
            }
        } else {
            // Not cutting: a flexible tool still rings down (and is heard).
            if let Some(flex) = self.flex.as_mut() {
                let none = EndCut::new(0.0, p[2], false);
                flex_to(
                    flex,
                    &self.cutter,
                    &self.stock,
                    t_s,
                    self.rpm,
                    p,
                    [0.0; 2],
                    0.0,
                    none,
                    None,
                );
            }
            Forces::default()
        };
        self.end_engaged = f.end_engaged;
        let (fx, fy, t) = (f.fx, f.fy, f.t);
        // The stock is cut where the tool is: a flexible tool's deflection moves it.
        let defl = |q: [f64; 3], f: Option<&Flex>| match f {
            Some(f) => {
                let d = f.deflection_mm();
                [q[0] + d[0], q[1] + d[1], q[2]]
            }
            None => q,
        };
        let here = defl(p, self.flex.as_ref());
        if let Some(a) = prev {
            self.stock
                .cut_shaped(a, here, self.cutter.r_mm, self.cutter.shape);
        } else {
            self.stock
                .cut_shaped(here, here, self.cutter.r_mm, self.cutter.shape);
        }
        // Holder frame: u at world angle -theta, v 90 degrees counter-clockwise from u.
        let (s, co) = theta.sin_cos();
        let fu = fx * co - fy * s;
        let fv = fx * s + fy * co;
        let values = [t, fu, fv];
        let tr = self.transducer;
        let mut codes = [0u16; 3];
        for (ch, code) in codes.iter_mut().enumerate() {
            let noise = self.rng.gaussish() * tr.noise_sigma_codes;
            let x = (values[ch] / tr.gain[ch] + tr.offset[ch] + noise).round();
            *code = x.clamp(0.0, 4095.0) as u16;
        }
        Sample {
            f_true_n: fx.hypot(fy),
            t_true_nm: t,
            fu_n: fu,
            fv_n: fv,
            fa_n: f.fa,
            codes,
        }
    }
}

/// Integrates the flexible tool from its fine time to `t_s` (the commanded tip `p`, feed
/// direction `u`, feed per tooth `c` and end cut `end` held over the sample interval, the spindle
/// angle advancing), feeding the microphone; the forces at `t_s` of the deflected tool.
#[allow(clippy::too_many_arguments)]
fn flex_to(
    flex: &mut Flex,
    cutter: &Cutter,
    stock: &Stock,
    t_s: f64,
    rpm: f64,
    p: [f64; 3],
    u: [f64; 2],
    c: f64,
    end: EndCut,
    teeth: Option<&[f64]>,
) -> Forces {
    let tooth_s = 60.0 / (rpm * cutter.flutes as f64);
    if (tooth_s - flex.tooth_s).abs() > 1e-12 * tooth_s {
        // A new spindle speed: a new delay (the old surface's waviness is forgotten).
        flex.size_for(tooth_s);
    }
    let at = |flex: &Flex, theta: f64| {
        let now = flex.deflection_mm();
        let past = flex.ring.get(flex.at).copied().unwrap_or(now);
        let wave = [now[0] - past[0], now[1] - past[1]];
        cutter.forces(stock, p, theta, u, c, c, end, teeth, Some(wave))
    };
    while flex.t + flex.dt <= t_s {
        let theta = std::f64::consts::TAU * rpm * flex.t / 60.0;
        let f = at(flex, theta);
        let now = flex.deflection_mm();
        if let Some(slot) = flex.ring.get_mut(flex.at) {
            *slot = now;
        }
        flex.at = (flex.at + 1) % flex.ring.len().max(1);
        flex.x.step(f.fx, flex.dt);
        flex.y.step(f.fy, flex.dt);
        flex.t += flex.dt;
        let (vx, vy) = (flex.x.velocity(), flex.y.velocity());
        if let Some(code) = flex.listener.hear_at(flex.t, vx, vy) {
            flex.sound.push_back(code);
        }
    }
    at(flex, std::f64::consts::TAU * rpm * t_s / 60.0)
}
