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
//!   the position. Z motion does not make chips (the end face does not cut).
//! - Tooth k cuts when it faces the feed (`cos(alpha) = r_k . u > 0`, so entry and exit angles
//!   come from the geometry) and material is there: the axial depth is `a = top - max(tip Z,
//!   floor)` read in the cell of the material this edge meets next: from the edge point one cell
//!   inside the tool (`E = C + (R - cell) r_k`, lateral offset `y` from the path line) along the
//!   feed to one cell beyond the envelope of the discs already swept along a straight path
//!   (`P = E + (x_env - (R - cell) cos(alpha) + m) u`, `x_env = sqrt(R^2 - y^2)`, the margin
//!   `m = min(cell R / x_env, 8 cell)` puts P one cell beyond the envelope along its normal). So
//!   the cells the last samples cleared are not read as air on a first pass, and on a second
//!   pass along the same straight path every probe falls inside the cleared slot (cell centres
//!   within R of the path) and reads air. Artefact: the probe runs up to `x_env + m` (about
//!   2.7 mm for a 0.5 in tool) ahead of the edge, so within that distance of the end of a slot
//!   already cut a second pass still reads the material beyond its end. When the motion stops,
//!   `c` falls to zero over one tooth period (a real tool also cuts its last, thinning chips).
//!   Chip `h = c cos(alpha)` (the paper's `c sin(phi)` with phi measured from the entry side);
//!   `Ft = Ks a h`, `Fr = Kr Ft`.
//! - Force on the tool: `Ft` against the cutting speed, `Fr` towards the axis; X/Y resultant
//!   summed over the teeth; torque `T = R sum Ft`. `Fu`, `Fv`: the resultant in the holder frame
//!   rotating with the spindle (`u` axis at world angle `-theta`, `v` 90 degrees
//!   counter-clockwise from it), so `F = sqrt(Fu^2 + Fv^2)` is invariant.
//! - Removal after the force: cells within R of the segment from the previous sample's position
//!   to this one get `top = min(top, tip Z)`.
use std::collections::VecDeque;

use crate::drive::{Drive, DriveModel};
use crate::{validate, CutError, Material, Stock, Tool, Transducer, MM_PER_BLU};

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
    /// 12-bit ADC codes [T, Fu, Fv] with noise.
    pub codes: [u16; 3],
}

/// Geometry and model constants shared by the process and the oracle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cutter {
    pub r_mm: f64,
    pub flutes: u32,
    pub ks: f64,
    pub kr: f64,
    /// Probe margin (one cell), see the module docs.
    pub probe_mm: f64,
}

impl Cutter {
    pub fn new(tool: &Tool, material: &Material, stock: &Stock) -> Cutter {
        Cutter {
            r_mm: tool.diameter_mm / 2.0,
            flutes: tool.flutes,
            ks: material.ks_n_mm2,
            kr: material.kr,
            probe_mm: stock.cell_mm(),
        }
    }

    /// Force (Fx, Fy) in N on the tool and torque in N*m of all teeth at spindle angle `theta`
    /// (rad, clockwise), tool tip at `tip` (mm), unit feed direction `u` (XY), feed per tooth
    /// `c` (mm).
    pub fn forces(
        &self,
        stock: &Stock,
        tip: [f64; 3],
        theta: f64,
        u: [f64; 2],
        c: f64,
    ) -> [f64; 3] {
        let (mut fx, mut fy, mut t) = (0.0, 0.0, 0.0);
        let base = tip[2].max(stock.floor_mm());
        let pitch = std::f64::consts::TAU / self.flutes as f64;
        for k in 0..self.flutes {
            let psi = -theta - k as f64 * pitch;
            let (s, co) = psi.sin_cos();
            let cos_a = co * u[0] + s * u[1];
            if cos_a <= 0.0 {
                continue;
            }
            // The edge point a cell inside the tool (y: lateral offset from the path line), then
            // along the feed to one cell beyond the envelope of the swept discs.
            let re = self.r_mm - self.probe_mm;
            let y = re * (co * u[1] - s * u[0]);
            let x_env = (self.r_mm * self.r_mm - y * y).sqrt();
            let margin = (self.probe_mm * self.r_mm / x_env).min(8.0 * self.probe_mm);
            let ahead = x_env - re * cos_a + margin;
            let px = tip[0] + re * co + ahead * u[0];
            let py = tip[1] + re * s + ahead * u[1];
            let a = stock.top_at(px, py) - base;
            if a <= 0.0 {
                continue;
            }
            let ft = self.ks * a * c * cos_a;
            let fr = self.kr * ft;
            fx += -ft * s - fr * co;
            fy += ft * co - fr * s;
            t += ft * self.r_mm / 1000.0;
        }
        [fx, fy, t]
    }
}

/// SplitMix64 (Steele, Lea and Flood 2014): a fixed, tiny, well-mixed generator.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Gaussian-ish: the sum of twelve uniforms on [0, 1) minus 6 (mean 0, variance 1, |x| < 6).
    fn gaussish(&mut self) -> f64 {
        (0..12)
            .map(|_| (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
            .sum::<f64>()
            - 6.0
    }
}

/// The simulated cutting process (stock, tool, material, spindle, transducer, noise).
#[derive(Clone, Debug)]
pub struct Process {
    stock: Stock,
    tool: Tool,
    rpm: f64,
    transducer: Transducer,
    cutter: Cutter,
    rng: SplitMix64,
    /// (t, tip position mm) of the samples of the last tooth period and one before it.
    hist: VecDeque<(f64, [f64; 3])>,
    /// The feed drives: the commanded position (pulses) to where the tool is.
    drive_model: DriveModel,
    drive: Option<Drive>,
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
            rpm: spindle_rpm,
            transducer,
            cutter,
            rng: SplitMix64(seed),
            hist: VecDeque::new(),
            drive_model: DriveModel::Stepper,
            drive: None,
        })
    }

    /// The process behind feed drives of `model` (the default: a stepper, the tool where the
    /// pulses put it). The drive starts at rest at the first sample's commanded position.
    pub fn with_drive(mut self, model: DriveModel) -> Self {
        self.drive_model = model;
        self.drive = None;
        self
    }

    /// The stock as cut so far.
    pub fn stock(&self) -> &Stock {
        &self.stock
    }

    /// The stock as cut so far, consuming the process (to cut it again with another process).
    pub fn into_stock(self) -> Stock {
        self.stock
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
        let [fx, fy, t] = if dt > 0.0 && dxy > 0.0 {
            let c = dxy / (z * self.rpm / 60.0 * dt);
            self.cutter
                .forces(&self.stock, p, theta, [dx / dxy, dy / dxy], c)
        } else {
            [0.0; 3]
        };
        if let Some(a) = prev {
            self.stock.cut_capsule(a, p, self.cutter.r_mm);
        } else {
            self.stock.cut_capsule(p, p, self.cutter.r_mm);
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
            codes,
        }
    }
}
