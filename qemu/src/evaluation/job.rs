//! The whole die-sinking job of Fig. 1 from the cavity's geometry (host: the demo, `millac-qemu
//! job`, the tests): the program with a tool change between its four cutters, the tool table
//! (`$T` lines) and the blank, as [`Job`]. Tlusty, Koren and McNeil: "rough machining starts
//! with drilling a flat bottomed hole in position 1. A cutter with a comparatively large
//! diameter is used first starting from this hole, moving to Pt 2, Pt 3, Pt 4 ... After this
//! operation stock f is left to be removed by a smaller diameter cutter in the corners and by a
//! ball ended cutter on the steps of the sloped bottom."
//!
//! The plan (inches, G20; the cavity a rectangle whose bottom is a plane sloping up along +X):
//! 1. **T1, the drill**: the flat-bottomed start hole at Pt 1, at the deep end, one cutter
//!    radius (and a little) in from the end wall, deep enough that the roughing cutter goes down
//!    to its first stair in air. Fig. 1's is a slot drill (a two-flute center-cutting end mill,
//!    the paper's "flat bottomed hole"); a twist drill's point would go below the slope there, so
//!    with one (`ToolKind::Drill`) the hole stops with its point on the slope's allowance and
//!    the roughing cutter's end face takes the rest of the cone.
//! 2. **T2, the roughing end mill**: stairs down the slope, deepest first ("cut A"): each stair
//!    a full-width slot along the cavity's centre line at the stair's depth (from the hole, then
//!    from the stair before), then loops around it `e` wider each time (the paper's side cuts
//!    B, C, of width e < d/2) out to the walls. A stair's depth leaves `allowance` above the
//!    slope under the whole cutter, so the slope keeps stock: the steps.
//! 3. **T3, the corner end mill**: the roughing cutter leaves its radius in the four corners;
//!    the small end mill cleans each corner in levels down to the stair's bottom there, an L
//!    along one wall into the corner and out along the other.
//! 4. **T4, the ball end mill**: the steps of the sloped bottom, in rasters along the slope
//!    (zig-zag, stepping across at the walls), the tip on the plane offset so the sphere touches
//!    it.
//!
//! The stock's grid is fine enough for the smallest cutter (its radius over 24, at most the
//! plant's 0.25 mm; `qemu/plant`'s halving test shows what a finer one changes).
use std::fmt::Write as _;

use millac::gcode::tools::ToolKind;

/// mm per inch.
const MM: f64 = 25.4;

/// The cavity and the blank, inches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cavity {
    /// The cavity's rectangle: X `x[0]..x[1]`, Y `y[0]..y[1]`.
    pub x: [f64; 2],
    pub y: [f64; 2],
    /// Its bottom's Z at `x[0]` and at `x[1]`: a plane sloping along X.
    pub z: [f64; 2],
    /// The blank: X 0..`blank[0]`, Y 0..`blank[1]`, its top at Z0.
    pub blank: [f64; 2],
}

impl Cavity {
    /// The cavity of Fig. 1 as the demo's roughing program has it: X1..4, Y0.8..2.2 in the 5 x 3
    /// in blank, the bottom at Z-0.6 at the deep end rising to Z-0.45 at the other.
    pub const FIG1: Cavity = Cavity {
        x: [1.0, 4.0],
        y: [0.8, 2.2],
        z: [-0.6, -0.45],
        blank: [5.0, 3.0],
    };

    /// The bottom's Z at `x` (in).
    pub fn bottom(&self, x: f64) -> f64 {
        self.z[0] + (self.z[1] - self.z[0]) * (x - self.x[0]) / (self.x[1] - self.x[0])
    }

    /// The bottom's slope dZ/dX.
    fn slope(&self) -> f64 {
        (self.z[1] - self.z[0]) / (self.x[1] - self.x[0])
    }

    fn y_mid(&self) -> f64 {
        0.5 * (self.y[0] + self.y[1])
    }
}

/// One cutter of the job: its tool number, what the tool table says of it (diameter in mm,
/// flutes, kind; its limits are the table's own where given, else from its geometry), the
/// spindle speed and the feeds the programmer writes for it (ipm): `feed_ipm` cutting (at
/// most: a cut that starts at full engagement takes [`Cutter::first_tooth_ipm`]), `entry_ipm`
/// going down (the roughing cutter into the hole, the corner end mill to each level, the ball
/// end mill onto the slope).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cutter {
    pub number: u8,
    pub diameter_mm: f64,
    pub flutes: u8,
    pub kind: ToolKind,
    /// The permissible force and torque the table gives (N, N m; 0: from the geometry).
    pub limits: [f64; 2],
    pub rpm: u32,
    pub feed_ipm: f64,
    pub entry_ipm: f64,
}

/// The specific cutting force the programmer takes for steel, N/mm^2 (a handbook's kc for a
/// medium-carbon steel; the plant's steel has the same).
pub const KC_STEEL: f64 = 2000.0;

/// The share of a cutter's permissible force the programmer lets one tooth take at full chip
/// (the adaptive control's F0 is 0.9 of it).
pub const FIRST_TOOTH_SHARE: f64 = 0.85;

impl Cutter {
    /// The radius, inches.
    fn r(&self) -> f64 {
        self.diameter_mm / MM / 2.0
    }

    /// The permissible radial force, N: the table's, else from the geometry (HSS).
    pub fn force_limit_n(&self) -> f64 {
        if self.limits[0] > 0.0 {
            return self.limits[0];
        }
        millac::ac::strength::derived(
            self.kind,
            self.diameter_mm as f32,
            &millac::ac::strength::Strength::HSS,
        )
        .map_or(f64::INFINITY, |l| f64::from(l.force_n))
    }

    /// The feed (ipm, at most `feed_ipm`, down to 0.1 ipm) at which a tooth meeting `depth_in`
    /// of material with the whole feed per tooth as its chip takes [`FIRST_TOOTH_SHARE`] of the
    /// permissible force: `Kc a c`. A cut that starts at full engagement (a slot's first tooth,
    /// a side cut's, a step sideways into the wall) loads its first tooth so before any control
    /// can act: the programmer's feed must be safe for it.
    pub fn first_tooth_ipm(&self, depth_in: f64) -> f64 {
        let a_mm = depth_in * MM;
        let c_mm = FIRST_TOOTH_SHARE * self.force_limit_n() / (KC_STEEL * a_mm);
        let ipm = c_mm * f64::from(self.flutes) * f64::from(self.rpm) / MM;
        (ipm.min(self.feed_ipm) * 10.0).floor() / 10.0
    }

    /// The tool table's line for it (`$T` as typed at the console).
    fn table_line(&self) -> String {
        let mut l = format!(
            "$T{}=D{} N{} K{}",
            self.number,
            self.diameter_mm,
            self.flutes,
            self.kind.code()
        );
        if self.limits[0] > 0.0 {
            let _ = write!(l, " F{}", self.limits[0]);
        }
        if self.limits[1] > 0.0 {
            let _ = write!(l, " M{}", self.limits[1]);
        }
        l
    }
}

/// The four cutters of the job.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cutters {
    pub drill: Cutter,
    pub rough: Cutter,
    pub corner: Cutter,
    pub ball: Cutter,
}

impl Cutters {
    /// Fig. 1's: a 14 mm slot drill (two flutes, at 450 rpm), the paper's 0.5 in four-flute end mill
    /// with its 4000 N and 80 N m (600 rpm), a 6 mm three-flute end mill for the corners and a
    /// 10 mm two-flute ball end mill (1200 and 800 rpm: about 23 and 25 m/min in steel, HSS).
    /// The small cutters' limits come from their geometry (`millac::ac::strength`).
    pub const FIG1: Cutters = Cutters {
        drill: Cutter {
            number: 1,
            diameter_mm: 14.0,
            flutes: 2,
            kind: ToolKind::Flat,
            limits: [0.0, 0.0],
            rpm: 450,
            feed_ipm: 4.0,
            entry_ipm: 4.0,
        },
        rough: Cutter {
            number: 2,
            diameter_mm: 12.7,
            flutes: 4,
            kind: ToolKind::Flat,
            limits: [4000.0, 80.0],
            rpm: 600,
            feed_ipm: 20.0,
            entry_ipm: 11.0,
        },
        corner: Cutter {
            number: 3,
            diameter_mm: 6.0,
            flutes: 3,
            kind: ToolKind::Flat,
            limits: [0.0, 0.0],
            rpm: 1200,
            feed_ipm: 12.0,
            entry_ipm: 4.0,
        },
        ball: Cutter {
            number: 4,
            diameter_mm: 10.0,
            flutes: 2,
            kind: ToolKind::Ball,
            limits: [0.0, 0.0],
            rpm: 800,
            feed_ipm: 20.0,
            entry_ipm: 6.0,
        },
    };
}

/// How the job is cut (inches).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The roughing's stairs down the slope.
    pub stairs: usize,
    /// Stock the roughing leaves above the slope (at the least).
    pub allowance: f64,
    /// The side cuts' width e (less than half the roughing cutter's diameter).
    pub side_cut: f64,
    /// The corner end mill's depth per level.
    pub corner_level: f64,
    /// The ball end mill's step between rasters.
    pub ball_step: f64,
    /// The height rapids cross the blank at.
    pub clear: f64,
    /// How far the ball end mill keeps from the walls (the plant's grid sees a wall one cell
    /// before an edge moving towards it touches it: a tool driven up to a wall loads its front
    /// tooth with the whole chip over the wall's height there; the corner end mill, which must
    /// reach the walls, enters each corner at a feed safe for that, see [`generate`]).
    pub wall_gap: f64,
}

impl Plan {
    pub const FIG1: Plan = Plan {
        stairs: 3,
        allowance: 0.01,
        side_cut: 0.225,
        corner_level: 0.15,
        ball_step: 0.15,
        clear: 0.1,
        wall_gap: 0.04,
    };
}

/// A generated job: the program, the tool table's lines and the blank's description (the
/// plant's stock file).
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    pub program: String,
    pub tools: String,
    pub stock: String,
}

impl Job {
    /// Its files' names and texts: `fig1-job.nc`, `.tools` and `.stock` (as shipped in
    /// `qemu/programs/`).
    pub fn files(&self) -> [(&'static str, &str); 3] {
        [
            ("fig1-job.nc", &self.program),
            ("fig1-job.tools", &self.tools),
            ("fig1-job.stock", &self.stock),
        ]
    }

    /// Writes its [`Job::files`] into `dir` (made if missing); the paths written.
    pub fn write(&self, dir: &std::path::Path) -> anyhow::Result<Vec<std::path::PathBuf>> {
        use anyhow::Context;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        self.files()
            .iter()
            .map(|(name, text)| {
                let path = dir.join(name);
                std::fs::write(&path, text)
                    .with_context(|| format!("writing {}", path.display()))?;
                Ok(path)
            })
            .collect()
    }
}

/// Fig. 1's whole job.
pub fn fig1() -> Job {
    generate(&Cavity::FIG1, &Cutters::FIG1, &Plan::FIG1)
}

/// A number in inches as the program writes it.
fn n(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// The job for `cavity` with `cutters` by `plan` (see the module docs).
pub fn generate(cavity: &Cavity, cutters: &Cutters, plan: &Plan) -> Job {
    let c = cavity;
    let mut p = String::new();
    let mut line = |s: String| {
        p += &s;
        p.push('\n');
    };
    let Cutters {
        drill,
        rough,
        corner,
        ball,
    } = cutters;
    line("(millac job: the die-sinking job of Fig. 1, Tlusty, Koren and McNeil, \"NC and AC for die sinking\")".into());
    line(format!(
        "(generated by millac-qemu job from the cavity's geometry: X{}..{} Y{}..{} in, bottom Z{} at X{} sloping to Z{} at X{}; blank X0..{} Y0..{}, top Z0)",
        n(c.x[0]), n(c.x[1]), n(c.y[0]), n(c.y[1]), n(c.z[0]), n(c.x[0]), n(c.z[1]), n(c.x[1]), n(c.blank[0]), n(c.blank[1])
    ));
    line("G20 G90 G17 G94".into());
    let clear = plan.clear;
    let ym = c.y_mid();

    // The roughing's stairs: tool centre X from `xs` to each `xb[k]`, at `zs[k]`.
    let r2 = rough.r();
    let (xs, xe) = (c.x[0] + r2, c.x[1] - r2);
    let k = plan.stairs.max(1);
    let xb: Vec<f64> = (1..=k)
        .map(|i| xs + (xe - xs) * i as f64 / k as f64)
        .collect();
    let zs: Vec<f64> = xb
        .iter()
        .map(|&x| c.bottom((x + r2).min(c.x[1])) + plan.allowance)
        .collect();
    let r1 = drill.r();
    // Pt 1: the hole's edge no nearer the end wall than the roughing cutter's.
    let pt1 = c.x[0] + r1.max(r2) + 0.005;
    // The hole's whole diameter below the first stair; a twist drill's point (118 degrees) no
    // deeper than the slope's allowance under it.
    let hole = match drill.kind {
        ToolKind::Drill => {
            let point = r1 / (59f64).to_radians().tan();
            (zs[0] - 0.02 - point).max(c.bottom(pt1) + plan.allowance)
        }
        _ => zs[0] - 0.02,
    };

    // 1. The start hole.
    line(format!(
        "(T{}: {} mm {}, the flat-bottomed start hole at Pt 1)",
        drill.number,
        drill.diameter_mm,
        match drill.kind {
            ToolKind::Drill => "drill",
            _ => "slot drill",
        }
    ));
    line(format!("T{} M6", drill.number));
    line(format!("S{} M3", drill.rpm));
    line(format!("G0 X{} Y{}", n(pt1), n(ym)));
    line(format!("G0 Z{}", n(clear)));
    line(format!(
        "G98 G81 X{} Y{} Z{} R{} F{}",
        n(pt1),
        n(ym),
        n(hole),
        n(clear),
        n(drill.feed_ipm)
    ));
    line("G80".into());

    // 2. The roughing: stairs, deepest first, each a slot and loops out to the walls.
    line(format!(
        "(T{}: {} in end mill, roughing: {} stairs down the slope, each a full-width slot then side cuts {} in wide)",
        rough.number,
        n(rough.diameter_mm / MM),
        k,
        n(plan.side_cut)
    ));
    line(format!("T{} M6", rough.number));
    line(format!("S{} M3", rough.rpm));
    line(format!("G0 X{} Y{}", n(pt1), n(ym)));
    line(format!("G0 Z{}", n(clear)));
    line(format!(
        "G1 Z{} F{}     (into the hole)",
        n(zs[0]),
        n(rough.entry_ipm)
    ));
    let half = (c.y[1] - c.y[0]) / 2.0 - r2;
    let mut offsets = Vec::new();
    let mut w = plan.side_cut;
    while w < half - 1e-9 {
        offsets.push(w);
        w += plan.side_cut;
    }
    offsets.push(half);
    for (i, (&x_end, &z)) in xb.iter().zip(&zs).enumerate() {
        let x_start = if i == 0 { xs } else { xb[i - 1] };
        if i > 0 {
            // The stair before ended at this one's start on the centre line: up to its depth.
            line(format!("G1 Z{}", n(z)));
        }
        // Every move of a stair meets its whole depth with the front tooth (see
        // `Cutter::first_tooth_ipm`).
        let f = rough.first_tooth_ipm(-z);
        line(format!(
            "G1 X{} Y{} F{}     (stair {}: slot at depth {} in)",
            n(x_end),
            n(ym),
            n(f),
            i + 1,
            n(-z)
        ));
        for &w in &offsets {
            line(format!("G1 Y{}", n(ym - w)));
            line(format!("G1 X{}", n(x_start)));
            line(format!("G1 Y{}", n(ym + w)));
            line(format!("G1 X{}", n(x_end)));
        }
        line(format!("G1 Y{}", n(ym)));
    }
    line(format!("G0 Z{}", n(clear)));

    // 3. The corners.
    let r3 = corner.r();
    line(format!(
        "(T{}: {} mm end mill, the four corners the roughing cutter leaves its radius in, {} in a level)",
        corner.number,
        corner.diameter_mm,
        n(plan.corner_level)
    ));
    line(format!("T{} M6", corner.number));
    line(format!("S{} M3", corner.rpm));
    // The stair's depth under a corner: the stair whose slot reaches it.
    let stair_at = |x: f64| {
        let i = xb.iter().position(|&b| x <= b + r2 + 1e-9).unwrap_or(k - 1);
        zs[i]
    };
    for (cx, dx) in [(c.x[0], 1.0), (c.x[1], -1.0)] {
        for (cy, dy) in [(c.y[0], 1.0), (c.y[1], -1.0)] {
            let floor = stair_at(cx + dx * r2);
            // Along the end wall into the corner, out along the side wall.
            let a = [cx + dx * r3, cy + dy * (r2 + r3)];
            let corner_pt = [cx + dx * r3, cy + dy * r3];
            let b = [cx + dx * (r2 + r3), cy + dy * r3];
            line(format!("G0 X{} Y{}", n(a[0]), n(a[1])));
            line(format!("G0 Z{}", n(clear)));
            let mut z = 0.0;
            loop {
                let above = z;
                z = (z - plan.corner_level).max(floor);
                line(format!("G1 Z{} F{}", n(z), n(corner.entry_ipm)));
                // Into the corner at the level's depth, the last `wall_gap` up to the side
                // wall slower: the wall's whole height below the top meets the front tooth
                // there (see `Plan::wall_gap`); out along the side wall, the level's depth.
                let level_ipm = corner.first_tooth_ipm(above - z);
                line(format!(
                    "G1 X{} Y{} F{}",
                    n(corner_pt[0]),
                    n(corner_pt[1] + dy * plan.wall_gap),
                    n(level_ipm)
                ));
                line(format!(
                    "G1 Y{} F{}",
                    n(corner_pt[1]),
                    n(corner.first_tooth_ipm(-z))
                ));
                line(format!("G1 X{} Y{} F{}", n(b[0]), n(b[1]), n(level_ipm)));
                line(format!("G0 X{} Y{}", n(a[0]), n(a[1])));
                if z <= floor {
                    break;
                }
            }
            line(format!("G0 Z{}", n(clear)));
        }
    }

    // 4. The sloped bottom's steps: rasters along X, the tip on the plane offset so the sphere
    //    touches it (R (sqrt(1 + m^2) - 1) above the plane under the tip).
    let r4 = ball.r();
    let m = c.slope();
    let lift = r4 * ((1.0 + m * m).sqrt() - 1.0);
    let tip = |x: f64| c.bottom(x) + lift;
    let g = plan.wall_gap;
    let (bx0, bx1) = (c.x[0] + r4 + g, c.x[1] - r4 - g);
    let (by0, by1) = (c.y[0] + r4 + g, c.y[1] - r4 - g);
    let lines = ((by1 - by0) / plan.ball_step).ceil().max(1.0) as usize;
    // The most stock on the slope: a stair's depth over the slope at the near end of its
    // cutter's reach (the stair's length and the roughing cutter's diameter up the slope).
    let stock_max = plan.allowance + m * ((xe - xs) / k as f64 + 2.0 * r2);
    let ball_ipm = ball.first_tooth_ipm(stock_max);
    line(format!(
        "(T{}: {} mm ball end mill, the steps of the sloped bottom: {} rasters along the slope, {} in apart)",
        ball.number,
        ball.diameter_mm,
        lines + 1,
        n((by1 - by0) / lines as f64)
    ));
    line(format!("T{} M6", ball.number));
    line(format!("S{} M3", ball.rpm));
    line(format!("G0 X{} Y{}", n(bx0), n(by0)));
    line(format!("G0 Z{}", n(clear)));
    line(format!("G1 Z{} F{}", n(tip(bx0)), n(ball.entry_ipm)));
    for i in 0..=lines {
        let y = by0 + (by1 - by0) * i as f64 / lines as f64;
        let x = if i % 2 == 0 { bx1 } else { bx0 };
        if i > 0 {
            let from = if i % 2 == 0 { bx0 } else { bx1 };
            line(format!("G1 Y{} Z{}", n(y), n(tip(from))));
        }
        line(format!("G1 X{} Z{} F{}", n(x), n(tip(x)), n(ball_ipm)));
    }
    line(format!("G0 Z{}", n(clear)));
    line("M5".into());
    line("G0 X0 Y0".into());
    line("M2".into());

    let mut tools = String::from("# the tool table of the Fig. 1 job (millac-qemu job)\n");
    for t in [drill, rough, corner, ball] {
        let _ = writeln!(
            tools,
            "{}   ({})",
            t.table_line(),
            match t.kind {
                ToolKind::Drill => "drill",
                ToolKind::Ball => "ball end mill",
                ToolKind::Flat => "end mill",
            }
        );
    }
    let smallest = [drill, rough, corner, ball]
        .iter()
        .map(|t| t.diameter_mm)
        .fold(f64::INFINITY, f64::min);
    let cell = grid_mm(smallest);
    let stock = format!(
        "# the blank of the Fig. 1 job (millac-qemu job): cells of {cell} mm, the smallest cutter's radius over 24\ncell {cell}\nblank X0 Y0 W{} H{} Z0\n",
        n(c.blank[0]),
        n(c.blank[1])
    );
    Job {
        program: p,
        tools,
        stock,
    }
}

/// The stock's cell for a job whose smallest cutter is `diameter_mm`: its radius over 24,
/// rounded down to a power-of-two fraction of 0.25 mm (the plant's coarsest; halvings of the
/// grid keep the cells' edges).
pub fn grid_mm(diameter_mm: f64) -> f64 {
    let want = diameter_mm / 2.0 / 24.0;
    let mut cell = 0.25;
    while cell > want {
        cell /= 2.0;
    }
    cell
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped files are the generator's (not hand-typed): `qemu/programs/fig1-job.*`.
    #[test]
    fn the_shipped_job_is_the_generators() {
        let j = fig1();
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/programs");
        for (name, text) in j.files() {
            let shipped = std::fs::read_to_string(format!("{dir}/{name}")).unwrap();
            assert_eq!(
                &shipped, text,
                "{name}: run `millac-qemu job --out qemu/programs`"
            );
        }
    }

    #[test]
    fn the_grid_is_a_halving_of_the_plants_finest_fitting_the_smallest_radius() {
        assert_eq!(grid_mm(12.7), 0.25);
        assert_eq!(grid_mm(6.0), 0.125);
        assert_eq!(grid_mm(3.0), 0.0625);
        assert_eq!(grid_mm(2.0), 0.03125);
    }

    /// Every stair stays `allowance` above the slope under the whole cutter, and the deepest
    /// cuts nothing below the slope anywhere: the ball end mill has stock everywhere.
    #[test]
    fn the_roughing_leaves_stock_on_the_slope() {
        let j = fig1();
        let c = Cavity::FIG1;
        let r = Cutters::FIG1.rough.r();
        let mut in_rough = false;
        let (mut x, mut z) = (0.0, 0.0);
        for l in j.program.lines() {
            if l.starts_with("T2 M6") {
                in_rough = true;
            }
            if l.starts_with("T3 M6") {
                break;
            }
            if !in_rough || !l.starts_with("G1") {
                continue;
            }
            for w in l.split_whitespace() {
                if let Some(v) = w.strip_prefix('X') {
                    x = v.parse().unwrap();
                }
                if let Some(v) = w.strip_prefix('Z') {
                    z = v.parse().unwrap();
                }
            }
            // Under the whole cutter at this end point (the bottom rises along +X).
            let worst = c.bottom((x + r).min(c.x[1]));
            assert!(z >= worst, "{l}: Z{z} below the slope's {worst}");
        }
        assert!(in_rough);
    }
}
