//! A cutter's permissible radial force and spindle torque from its geometry (core: the loader task
//! at an M6, `crate::rt::status::FittedTool::of`, and the host's runs). The paper: "the end milling cutter may
//! break in bending or in twist or its tooth may break away"; it left the limits to a strength
//! study "still in the initial stage". Here the first two, as beams:
//!
//! - **Bending**: the cutter is a cantilever of length `L` (its overhang out of the holder) loaded
//!   by the radial force `F` at its end; the largest stress, at the holder, is
//!   `sigma = 32 F L / (pi d_e^3)`, so `F_max = sigma_a pi d_e^3 / (32 L)`.
//! - **Twist**: the torque `T` twists the fluted section; `tau = 16 T / (pi d_e^3)`, so
//!   `T_max = tau_a pi d_e^3 / 16` with `tau_a = sigma_a / sqrt(3)` (von Mises).
//!
//! `d_e` is the fluted section's equivalent diameter, 0.8 D (Kops and Vo, "Determination of the
//! equivalent diameter of an end mill based on its compliance", CIRP Annals 39/1, 1990: a solid
//! cylinder of 0.8 D deflects as two- and four-flute end mills do). The allowable stress
//! `sigma_a` is the cutter material's bending strength over a safety factor ([`Strength::HSS`]:
//! about 3000 MPa transverse rupture strength of M2 high-speed steel over 3: 1000 MPa; a brittle
//! fracture, the paper's "difficult aspect", is what the factor is for). The overhang is a
//! multiple of the diameter: 2 D for end mills (a standard length of cut), 4 D for drills (a
//! stub drill's flutes). A tooth breaking away (a three-dimensional stress problem) is not
//! modelled: the breakage monitor watches for it.
//!
//! For the Fig. 1 cutter (0.5 in, flat): `F_max` = 4054 N, the paper's example's 4000 N; its
//! torsion limit, 118.9 N m, is above the 80 N m the demo sets (the spindle's torque, not the
//! cutter's, limits there). A 3 mm end mill: 226 N and 1.57 N m.
//!
//! Arithmetic is f32, as the AC's.

use crate::gcode::tools::ToolKind;

/// The strength model's constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strength {
    /// Allowable bending stress, MPa (N/mm^2): the cutter material's strength over the safety
    /// factor. Twist is allowed `1 / sqrt(3)` of it.
    pub allowable_mpa: f32,
    /// Overhang of end mills (flat and ball) and of drills, in diameters.
    pub mill_overhang_d: f32,
    pub drill_overhang_d: f32,
}

impl Strength {
    /// High-speed steel cutters: 1000 MPa (about 3000 MPa of M2 over a safety factor of 3), end
    /// mills out 2 D, drills 4 D.
    pub const HSS: Strength = Strength {
        allowable_mpa: 1000.0,
        mill_overhang_d: 2.0,
        drill_overhang_d: 4.0,
    };
}

/// The equivalent diameter of a fluted section over the cutter's diameter (Kops and Vo).
pub const EQUIVALENT_D: f32 = 0.8;

/// `1 / sqrt(3)`: the von Mises ratio of the allowable shear to the allowable normal stress.
const VON_MISES_SHEAR: f32 = 0.577_350_26;

/// A cutter's permissible radial force (N) and torque (N m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub force_n: f32,
    pub torque_nm: f32,
}

/// The limits of a cutter of `kind` and `diameter_mm` under `s`; None for a diameter that is not
/// finite and > 0 (a tool nobody described).
pub fn derived(kind: ToolKind, diameter_mm: f32, s: &Strength) -> Option<Limits> {
    if !(diameter_mm > 0.0 && diameter_mm.is_finite()) {
        return None;
    }
    let de = EQUIVALENT_D * diameter_mm;
    let section = core::f32::consts::PI * de * de * de;
    let overhang = match kind {
        ToolKind::Flat | ToolKind::Ball => s.mill_overhang_d,
        ToolKind::Drill => s.drill_overhang_d,
    } * diameter_mm;
    Some(Limits {
        force_n: s.allowable_mpa * section / (32.0 * overhang),
        // N mm -> N m.
        torque_nm: s.allowable_mpa * VON_MISES_SHEAR * section / 16.0 / 1000.0,
    })
}

/// Where a tool's limits come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The tool table's own (`$T`'s F and M words), both given.
    Table,
    /// Derived from the tool's kind and diameter ([`derived`]), for those the table leaves 0.
    Geometry,
}

/// The limits of tool `t`: each of the table's own where it gives one (not 0), the rest derived
/// from its geometry under `s`; None when the table does not give both and the tool has no
/// diameter (fitted, the AC only measures it).
pub fn of_tool(t: &crate::gcode::tools::Tool, s: &Strength) -> Option<(Limits, Source)> {
    let (f, m) = (t.force_limit_n, t.torque_limit_nm);
    if f > 0.0 && m > 0.0 {
        return Some((
            Limits {
                force_n: f,
                torque_nm: m,
            },
            Source::Table,
        ));
    }
    // Picometres -> mm.
    let d = derived(t.kind, t.diameter_pm as f32 * 1e-9, s)?;
    Some((
        Limits {
            force_n: if f > 0.0 { f } else { d.force_n },
            torque_nm: if m > 0.0 { m } else { d.torque_nm },
        },
        Source::Geometry,
    ))
}
