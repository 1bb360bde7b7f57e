//! millac-plant (host): the simulated plant of millac, the machine the controller drives, modelled
//! on the host. Today that is the cutting process, the thing the simulated ADC measures: a flat end
//! mill cuts a height-map stock ([`stock`]); at every ADC sample [`Process::sample`] ([`process`])
//! computes the instantaneous cutting force and torque from the engagement at that instant
//! (mechanistic model of Munasinghe 1994, eq. 3.1 to 3.5: Ft = Ks a h, Fr = Kr Ft, h = c sin(phi);
//! optionally Kienzle's size effect Ks(h), and the end face cutting on plunges and ramps),
//! resolves the force in the rotating tool holder (Tlusty, Koren and McNeil: Fu, Fv 90 degrees
//! apart, F = sqrt(Fu^2 + Fv^2), torque T) and turns T, Fu, Fv into 12-bit ADC codes with seeded
//! noise. [`oracle`] computes the fastest feed schedule any controller could run along a tool path
//! with full knowledge of the stock: the bound the evaluation (millac-qemu's `acreport`, which turns
//! the NC program into the path) compares controllers with.
//!
//! The plant knows nothing of the controller: it does not depend on `millac` and reads none of its
//! settings. Its parameters are physical properties of the simulated machine ([`Tool`] strength,
//! [`Material`] coefficients, the [`Transducer`]'s real gain, offset and noise); the controller's
//! settings (e.g. its calibration) are its belief about them, set separately by whoever runs the
//! experiment, so an honest evaluation can make the two disagree. The defaults happen to agree with
//! the controller's defaults; millac-qemu's tests check that the default experiment is matched.
//! The feed drives ([`drive`]: a stepper, or the thesis' servo position loop) turn the commanded
//! position into where the tool really is; the wiring into runs comes with issue 9. [`teeth`]:
//! the cutter's per-tooth state, radial run-out and chipped or broken teeth (the thesis' section
//! 3.2: the next tooth takes the rest). Later models of the plant live here too: chatter.
//!
//! Units: the controller speaks BLU (0.0001 in, integers) and ipm at the plant's boundary (tool tip
//! positions in [`MM_PER_BLU`] steps, programmed feeds); inside, the plant works in SI: mm, s, N,
//! N*m (1 BLU = 0.00254 mm, 1 ipm = 25.4 / 60 mm/s). Stock descriptions are in inches like the G20
//! programs. Called from the host tool only (no firmware context).
//!
//! Determinism: no hash maps, no clocks, no threads; noise from a seeded SplitMix64 and a sum of
//! twelve uniforms (only + and *). Same inputs and seed give the same bytes on one platform (the
//! force model uses `sin`/`cos`, whose last bits may differ between libm implementations).
pub mod chatter;
pub mod drive;
pub mod lobes;
pub mod oracle;
pub mod process;
mod rng;
pub mod stock;
pub mod teeth;
#[cfg(test)]
mod tests;

pub use drive::{Drive, DriveModel};
pub use oracle::{oracle_time, OracleLimits, OracleOut, OraclePoint, OracleResult, OracleStream};
pub use process::{Process, Sample};
pub use stock::{Envelope, Stock, StockError};
pub use teeth::{Damage, Teeth, ToothEvent};

/// mm per BLU (0.0001 in).
pub const MM_PER_BLU: f64 = 0.00254;
/// mm per inch.
pub const MM_PER_IN: f64 = 25.4;
/// mm/s per ipm.
pub const MM_S_PER_IPM: f64 = 25.4 / 60.0;
/// Default spindle speed, rpm: the paper's assumption for steel ("the maximum spindle speed which
/// would be used (for steel machining) is 600 rpm").
pub const DEFAULT_RPM: f64 = 600.0;

/// What the cutter's edges are: a flat end mill, a ball end mill or a twist drill (see
/// [`process`] for how each cuts). Its profile is the height of the cutting edge above the tip at
/// radius `r` from the axis ([`Shape::lift_mm`]): 0 for the flat end, `R - sqrt(R^2 - r^2)` for
/// the ball, `r / tan(point / 2)` for the drill's cone.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Shape {
    /// Side teeth over the whole engaged depth, a flat end face (center cutting).
    #[default]
    Flat,
    /// A hemisphere of the tool's radius at the tip, the cylinder above it: the side edges cut
    /// in slices up the sphere, each at its own radius; the end edges where the sphere meets
    /// material below it.
    Ball,
    /// A twist drill of point angle `point_deg` (118 for the usual HSS drill): its two lips cut
    /// on the cone at the end as a center-cutting end face does; its margins do not cut (no side
    /// teeth: a drill is fed along its axis).
    Drill { point_deg: f64 },
}

impl Shape {
    /// The usual twist drill's point angle, degrees.
    pub const DRILL_POINT_DEG: f64 = 118.0;

    /// Height of the cutting edge above the tip at `r_mm` from the axis (mm) on a tool of radius
    /// `radius_mm` (`r_mm` beyond the radius: the rim's).
    #[inline]
    pub fn lift_mm(&self, radius_mm: f64, r_mm: f64) -> f64 {
        let r = r_mm.min(radius_mm);
        match *self {
            Shape::Flat => 0.0,
            Shape::Ball => radius_mm - (radius_mm * radius_mm - r * r).max(0.0).sqrt(),
            Shape::Drill { point_deg } => r / (point_deg.to_radians() / 2.0).tan(),
        }
    }
}

/// A cutter: flat end mill, ball end mill or drill ([`Shape`]). The helix is ignored: every flute is a straight line along the tool axis, so
/// a flute's whole engaged depth cuts at one angle (the force per tooth is `Ks a h` with `a` the
/// full axial engagement; a real helix spreads it over a range of angles and smooths the peaks).
/// The flute length is taken as unlimited. The end face cuts when the tool moves down into
/// material (plunges and ramps, see [`process`]): the end mill is taken as center cutting, every
/// end tooth reaching from the axis to the rim.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    pub diameter_mm: f64,
    pub flutes: u32,
    /// Permissible resultant radial force on the cutter, N (bending strength).
    pub f_max_n: f64,
    /// Permissible torque, N*m (twist strength of the cutter / the spindle drive).
    pub t_max_nm: f64,
    pub shape: Shape,
}

impl Default for Tool {
    /// The 0.5 in four-flute end mill of the Fig. 1 demo, permissible 4000 N and 80 N*m (the
    /// values the AC core's default limits assume; millac-qemu's tests check they agree).
    fn default() -> Self {
        Tool {
            diameter_mm: 0.5 * MM_PER_IN,
            flutes: 4,
            f_max_n: 4000.0,
            t_max_nm: 80.0,
            shape: Shape::Flat,
        }
    }
}

/// Workpiece material: specific cutting pressure `ks` (N/mm^2, tangential force per chip area)
/// at the reference chip thickness [`H_REF_MM`], its size-effect exponent `ks_exponent`, the
/// radial force ratio `kr` = Fr / Ft of the side teeth and the axial force ratio `ka` = Fa / Ft
/// of the end teeth.
///
/// The thesis gives the model but no coefficient values (its tests cut Al 7075-T6 with HSS), so
/// the presets are textbook choices: steel Ks = 2000 N/mm^2 (medium-carbon steel such as AISI 1045
/// at chips around 0.1 mm: Kienzle kc1.1 about 1700..2200 N/mm^2), aluminium Ks = 800 N/mm^2 (Al
/// 7075-T6: Altintas' mechanistic Ktc about 800 N/mm^2, the Munasinghe/Altintas lab material),
/// and Kr = 0.3 for both (Tlusty's usual ratio for sharp end mills).
///
/// Size effect (the thesis' "non linear region of the cutting forces", section 5.3.1), Kienzle's
/// form: `Ks(h) = ks * (max(h, H_MIN_MM) / H_REF_MM)^(-ks_exponent)`, so `ks` is the value at
/// h = 0.1 mm and the tooth force `Ks(h) a h` grows as `h^(1 - m)`. `ks_exponent` = 0 (the
/// presets) keeps Ks constant, the force exactly proportional to the feed per tooth. Steel's
/// usual Kienzle exponent is about 0.25 ([`Material::STEEL_KIENZLE`]). The clamp at
/// [`H_MIN_MM`] = 0.005 mm (about the edge radius of a sharp tool) keeps Ks finite where a tooth
/// enters or leaves the cut (h = c cos(alpha) -> 0): below it Ks stays at its 0.005 mm value and
/// the force is linear in h.
///
/// End face: `ka` = 0.5 for both presets (axial force of the end teeth half their tangential
/// force; drilling-like cutting at the end face of a flat end mill, textbook range 0.4..1). The
/// end teeth's radial force is not modelled (Fr = 0 there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub ks_n_mm2: f64,
    pub kr: f64,
    /// Kienzle exponent m of Ks(h) (0 = constant Ks), 0 <= m < 1.
    pub ks_exponent: f64,
    /// Axial force ratio of the end teeth, Fa / Ft, >= 0.
    pub ka: f64,
}

/// Reference chip thickness of [`Material::ks_n_mm2`], mm.
pub const H_REF_MM: f64 = 0.1;
/// Smallest chip thickness the size effect sees, mm (see [`Material`]).
pub const H_MIN_MM: f64 = 0.005;

impl Material {
    pub const STEEL: Material = Material {
        ks_n_mm2: 2000.0,
        kr: 0.3,
        ks_exponent: 0.0,
        ka: 0.5,
    };
    /// Steel with the size effect: the same Ks at 0.1 mm, Kienzle exponent 0.25.
    pub const STEEL_KIENZLE: Material = Material {
        ks_exponent: 0.25,
        ..Material::STEEL
    };
    pub const ALUMINIUM: Material = Material {
        ks_n_mm2: 800.0,
        kr: 0.3,
        ks_exponent: 0.0,
        ka: 0.5,
    };

    /// Specific cutting pressure at chip thickness `h_mm`, N/mm^2 (see the type's docs).
    #[inline]
    pub fn ks_at(&self, h_mm: f64) -> f64 {
        if self.ks_exponent == 0.0 {
            self.ks_n_mm2
        } else {
            self.ks_n_mm2 * (h_mm.max(H_MIN_MM) / H_REF_MM).powf(-self.ks_exponent)
        }
    }
}

/// The force/torque transducer and its ADC, as they really are (the controller's calibration is
/// its belief about them). `code = round(value / gain + offset + noise)`, clamped to 0..=4095;
/// a controller reads the value back as `gain * (code - offset)`. Channels in the order of the
/// codes: [T, Fu, Fv].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transducer {
    /// Engineering units per code: N*m/code for T, N/code for Fu, Fv.
    pub gain: [f64; 3],
    /// Code at zero load.
    pub offset: [f64; 3],
    /// Standard deviation of the additive noise, in codes (same for all channels). 0 = none.
    pub noise_sigma_codes: f64,
}

impl Default for Transducer {
    /// 0.05 N*m and 2.5 N per code (+-102.4 N*m and +-5120 N full scale), offset 2048, noise
    /// sigma 2 codes. The AC core's default calibration believes the same gains and offsets
    /// (checked by millac-qemu's tests, not here).
    fn default() -> Self {
        Transducer {
            gain: [0.05, 2.5, 2.5],
            offset: [2048.0; 3],
            noise_sigma_codes: 2.0,
        }
    }
}

/// Invalid process parameters (tool, rpm, transducer).
#[derive(Clone, Debug, PartialEq)]
pub struct CutError(pub String);

impl core::fmt::Display for CutError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CutError {}

/// Checks the parameters shared by [`Process::new`] and [`oracle_time`].
pub(crate) fn validate(tool: &Tool, material: &Material, rpm: f64) -> Result<(), CutError> {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    if !(pos(tool.diameter_mm) && tool.diameter_mm <= 200.0) {
        return Err(CutError(format!(
            "tool diameter must be in (0, 200] mm, got {}",
            tool.diameter_mm
        )));
    }
    if !(1..=32).contains(&tool.flutes) {
        return Err(CutError(format!(
            "tool flutes must be 1..=32, got {}",
            tool.flutes
        )));
    }
    if let Shape::Drill { point_deg } = tool.shape {
        if !(point_deg.is_finite() && (60.0..=180.0).contains(&point_deg)) {
            return Err(CutError(format!(
                "a drill's point angle must be in [60, 180] degrees, got {point_deg}"
            )));
        }
    }
    if !(pos(tool.f_max_n) && pos(tool.t_max_nm)) {
        return Err(CutError(
            "tool permissible force and torque must be finite and > 0".into(),
        ));
    }
    if !(pos(material.ks_n_mm2) && material.kr.is_finite() && material.kr >= 0.0) {
        return Err(CutError(
            "material Ks must be finite and > 0, Kr finite and >= 0".into(),
        ));
    }
    if !((0.0..1.0).contains(&material.ks_exponent)
        && material.ka.is_finite()
        && material.ka >= 0.0)
    {
        return Err(CutError(format!(
            "material Ks exponent must be in [0, 1) (got {}), Ka finite and >= 0 (got {})",
            material.ks_exponent, material.ka
        )));
    }
    validate_rpm(rpm)
}

/// Checks a spindle speed: (0, 100000] rpm.
pub(crate) fn validate_rpm(rpm: f64) -> Result<(), CutError> {
    if !(rpm.is_finite() && rpm > 0.0 && rpm <= 100_000.0) {
        return Err(CutError(format!(
            "spindle speed must be in (0, 100000] rpm, got {rpm}"
        )));
    }
    Ok(())
}
