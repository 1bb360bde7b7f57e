//! millac-plant (host): the simulated plant of millac, the machine the controller drives, modelled
//! on the host. Today that is the cutting process, the thing the simulated ADC measures: a flat end
//! mill cuts a height-map stock ([`stock`]); at every ADC sample [`Process::sample`] ([`process`])
//! computes the instantaneous cutting force and torque from the engagement at that instant
//! (mechanistic model of Munasinghe 1994, eq. 3.1 to 3.5: Ft = Ks a h, Fr = Kr Ft, h = c sin(phi)),
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
//! position into where the tool really is; the wiring into runs comes with issue 9. Later models
//! of the plant live here too: tool breakage, chatter.
//!
//! Units: the controller speaks BLU (0.0001 in, integers) and ipm at the plant's boundary (tool tip
//! positions in [`MM_PER_BLU`] steps, programmed feeds); inside, the plant works in SI: mm, s, N,
//! N*m (1 BLU = 0.00254 mm, 1 ipm = 25.4 / 60 mm/s). Stock descriptions are in inches like the G20
//! programs. Called from the host tool only (no firmware context).
//!
//! Determinism: no hash maps, no clocks, no threads; noise from a seeded SplitMix64 and a sum of
//! twelve uniforms (only + and *). Same inputs and seed give the same bytes on one platform (the
//! force model uses `sin`/`cos`, whose last bits may differ between libm implementations).
pub mod drive;
pub mod oracle;
pub mod process;
pub mod stock;
#[cfg(test)]
mod tests;

pub use drive::{Drive, DriveModel};
pub use oracle::{oracle_time, OracleLimits, OraclePoint, OracleResult};
pub use process::{Process, Sample};
pub use stock::{Stock, StockError};

/// mm per BLU (0.0001 in).
pub const MM_PER_BLU: f64 = 0.00254;
/// mm per inch.
pub const MM_PER_IN: f64 = 25.4;
/// mm/s per ipm.
pub const MM_S_PER_IPM: f64 = 25.4 / 60.0;
/// Default spindle speed, rpm: the paper's assumption for steel ("the maximum spindle speed which
/// would be used (for steel machining) is 600 rpm").
pub const DEFAULT_RPM: f64 = 600.0;

/// A flat end mill. The helix is ignored: every flute is a straight line along the tool axis, so
/// a flute's whole engaged depth cuts at one angle (the force per tooth is `Ks a h` with `a` the
/// full axial engagement; a real helix spreads it over a range of angles and smooths the peaks).
/// The flute length is taken as unlimited; the end face does not cut (plunges give no force).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    pub diameter_mm: f64,
    pub flutes: u32,
    /// Permissible resultant radial force on the cutter, N (bending strength).
    pub f_max_n: f64,
    /// Permissible torque, N*m (twist strength of the cutter / the spindle drive).
    pub t_max_nm: f64,
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
        }
    }
}

/// Workpiece material: specific cutting pressure `ks` (N/mm^2, tangential force per chip area)
/// and radial force ratio `kr` = Fr / Ft.
///
/// The thesis gives the model but no coefficient values (its tests cut Al 7075-T6 with HSS), so
/// the presets are textbook choices: steel Ks = 2000 N/mm^2 (medium-carbon steel such as AISI 1045
/// at chips around 0.1 mm: Kienzle kc1.1 about 1700..2200 N/mm^2), aluminium Ks = 800 N/mm^2 (Al
/// 7075-T6: Altintas' mechanistic Ktc about 800 N/mm^2, the Munasinghe/Altintas lab material),
/// and Kr = 0.3 for both (Tlusty's usual ratio for sharp end mills). Ks is constant: no size
/// effect, so the force is exactly proportional to the feed per tooth (the thesis' "non linear
/// region" at small chips is not modelled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub ks_n_mm2: f64,
    pub kr: f64,
}

impl Material {
    pub const STEEL: Material = Material {
        ks_n_mm2: 2000.0,
        kr: 0.3,
    };
    pub const ALUMINIUM: Material = Material {
        ks_n_mm2: 800.0,
        kr: 0.3,
    };
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
    if !(pos(rpm) && rpm <= 100_000.0) {
        return Err(CutError(format!(
            "spindle speed must be in (0, 100000] rpm, got {rpm}"
        )));
    }
    Ok(())
}
