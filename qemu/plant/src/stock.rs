//! The stock as a height map over XY (host): square cells (0.25 mm by default, never coarser), each
//! holding the Z of the material top in mm; below the top is material down to the floor (the
//! lowest blank bottom, unbounded unless given). Air is `f64::NEG_INFINITY`. Material removal
//! lowers the tops under the swept tool disc. Built from a small text description.
//!
//! The removal's memory: the stock counts the XY path the tool has swept over it (its odometer,
//! mm, advanced by every [`Stock::cut_capsule`]) and each cell keeps the odometer reading at which
//! the tool last lowered it (never: the cell is as described, e.g. a drilled hole). The process
//! reads it to tell the material a tooth is cutting now (lowered within the last few mm of path,
//! or still there) from air that was air before (an earlier pass, a hole): see
//! [`crate::process`].
//!
//! Stock description (inches, like the G20 programs; one statement per line; `#` starts a comment;
//! keywords and word letters are case-insensitive; words in any order, each once):
//!
//! ```text
//! cell 0.25                     # optional: cell size in mm, 0 < size <= 0.25 (default 0.25)
//! blank X0 Y0 W5 H3 Z0 [B-2]    # material: X..X+W, Y..Y+H, top face Z, optional bottom B
//! hole X1.25 Y1.5 D0.5 Z-0.6    # flat-bottomed drilled hole: removed down to Z within D/2
//! pocket X1 Y0.8 W3 H1.4 Z-0.3  # rectangular pocket: removed down to Z
//! ```
//!
//! The grid spans the union of the blanks' rectangles; outside it is air. Statements apply in
//! file order (a blank after a hole fills it again). A cell belongs to a shape when its centre
//! does.

/// The default stock: the die blank of Fig. 1 (Tlusty, Koren and McNeil) with the drilled start
/// hole at Pt 1, as in `qemu/programs/fig1-cavity.nc`.
pub const FIG1_STOCK: &str = "\
# die blank of Fig. 1: top face Z0, X 0..5 in, Y 0..3 in
blank X0 Y0 W5 H3 Z0
# flat-bottomed start hole at Pt 1, drilled before the program
hole X1.25 Y1.5 D0.5 Z-0.6
";

/// Largest grid, cells (guards against a typo asking for gigabytes).
const MAX_CELLS: usize = 40_000_000;

/// The space a stock must lie in, inches per axis X, Y, Z (the description's unit): every
/// edge of a blank or pocket, every hole's extent and every top Z (a blank's bottom B only needs
/// to be below its top). The host tool gives the machine's travel ([`Stock::parse_within`]), so
/// a typo such as `Z1e6` is refused with its line instead of a cut kilometres deep that takes
/// hours to simulate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope {
    pub min_in: [f64; 3],
    pub max_in: [f64; 3],
}

impl Envelope {
    /// `what` (`v` inches on `axis` 0..=2) inside, or the error of line `line`.
    fn check(&self, line: usize, what: &str, axis: usize, v: f64) -> Result<(), StockError> {
        let (lo, hi) = (self.min_in[axis], self.max_in[axis]);
        if (lo..=hi).contains(&v) {
            return Ok(());
        }
        Err(StockError {
            line,
            msg: format!(
                "{what} at {v} in lies outside the {} range {lo}..{hi} in",
                ["X", "Y", "Z"][axis]
            ),
        })
    }
}

/// A stock description error: 1-based line number and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct StockError {
    pub line: usize,
    pub msg: String,
}

impl core::fmt::Display for StockError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if self.line == 0 {
            write!(f, "stock: {}", self.msg)
        } else {
            write!(f, "stock line {}: {}", self.line, self.msg)
        }
    }
}

impl std::error::Error for StockError {}

/// A run of cell columns or rows.
type Cells = std::ops::RangeInclusive<usize>;

/// The cells under a tool's disc above a height ([`Stock::disc_mask`]).
pub struct DiscMask {
    i0: usize,
    j0: usize,
    w: usize,
    h: usize,
    bits: Vec<bool>,
    cx: f64,
    cy: f64,
    r_mm: f64,
    z: f64,
}

/// The height map.
#[derive(Clone, Debug, PartialEq)]
pub struct Stock {
    x0_mm: f64,
    y0_mm: f64,
    cell_mm: f64,
    nx: usize,
    ny: usize,
    top: Vec<f64>,
    floor_mm: f64,
    /// XY path length swept by [`Stock::cut_capsule`] so far, mm.
    odometer_mm: f64,
    /// Per cell: the odometer reading when the tool last lowered it, `NEG_INFINITY` for never.
    lowered_at: Vec<f64>,
    /// No cell's top is above it (the highest top when the stock was made; cuts only lower
    /// cells, so it stays a bound): a cut whose tip stays at or above it lowers nothing.
    max_top: Bound,
}

/// An upper bound of the tops ([`Stock::max_top`]): a cache, equal whatever its value, so two
/// stocks with the same cells compare equal however they were cut.
#[derive(Clone, Copy, Debug)]
struct Bound(f64);

impl PartialEq for Bound {
    fn eq(&self, _: &Bound) -> bool {
        true
    }
}

/// The highest top of `top` (`NEG_INFINITY` when every cell is empty: an empty cell's top is
/// `NEG_INFINITY`, the only value that is not finite).
fn highest(top: &[f64]) -> Bound {
    Bound(top.iter().copied().fold(f64::NEG_INFINITY, f64::max))
}

/// What a cell holds for a tool whose bottom is at some Z (see [`Stock::cell_class`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cell {
    /// Material above the tool's bottom.
    Material,
    /// Air the tool made within the recent path (it lowered the cell).
    Recent,
    /// Air that was air before: never lowered by the tool, lowered longer ago, or outside.
    Old,
}

enum Shape {
    Blank { r: [f64; 4], z: f64, b: Option<f64> },
    Hole { x: f64, y: f64, d: f64, z: f64 },
    Pocket { r: [f64; 4], z: f64 },
}

/// Reads `letter -> value` words of one statement: each allowed letter once, all numbers finite.
fn words(
    line: usize,
    kw: &str,
    toks: &[&str],
    allowed: &str,
    required: &str,
) -> Result<[Option<f64>; 26], StockError> {
    let err = |msg: String| StockError { line, msg };
    let mut v = [None; 26];
    for t in toks {
        let mut ch = t.chars();
        let letter = ch.next().unwrap_or(' ').to_ascii_uppercase();
        if !allowed.contains(letter) {
            return Err(err(format!(
                "{kw}: unexpected word '{t}' (allowed words: {})",
                allowed
                    .chars()
                    .map(|c| c.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            )));
        }
        let num: f64 = ch
            .as_str()
            .parse()
            .ok()
            .filter(|n: &f64| n.is_finite())
            .ok_or_else(|| err(format!("{kw}: '{t}' is not {letter} followed by a number")))?;
        let slot = &mut v[(letter as u8 - b'A') as usize];
        if slot.is_some() {
            return Err(err(format!("{kw}: word {letter} given twice")));
        }
        *slot = Some(num);
    }
    for l in required.chars() {
        if v[(l as u8 - b'A') as usize].is_none() {
            return Err(err(format!("{kw}: missing word {l}")));
        }
    }
    Ok(v)
}

impl Default for Stock {
    fn default() -> Self {
        Stock::parse(FIG1_STOCK).expect("FIG1_STOCK parses")
    }
}

impl Stock {
    /// Parses a stock description (see the module docs).
    pub fn parse(src: &str) -> Result<Stock, StockError> {
        Stock::parse_in(src, None)
    }

    /// Parses a stock description that must lie within `envelope` (see [`Envelope`]): a
    /// statement reaching outside it is refused with its line.
    pub fn parse_within(src: &str, envelope: &Envelope) -> Result<Stock, StockError> {
        Stock::parse_in(src, Some(envelope))
    }

    fn parse_in(src: &str, envelope: Option<&Envelope>) -> Result<Stock, StockError> {
        let mut cell_mm = 0.25;
        let mut shapes = Vec::new();
        for (i, raw) in src.lines().enumerate() {
            let line = i + 1;
            let text = raw.split('#').next().unwrap_or("");
            let toks: Vec<&str> = text.split_whitespace().collect();
            let Some((kw, rest)) = toks.split_first() else {
                continue;
            };
            let g = |w: &[Option<f64>; 26], l: char| w[(l as u8 - b'A') as usize].unwrap_or(0.0);
            let to_mm = |v: f64| v * crate::MM_PER_IN;
            let err = |msg: &str| StockError {
                line,
                msg: msg.into(),
            };
            match kw.to_ascii_lowercase().as_str() {
                "cell" => {
                    let v: Option<f64> = match rest {
                        [one] => one.parse().ok(),
                        _ => None,
                    };
                    match v {
                        Some(c) if c > 0.0 && c <= 0.25 => cell_mm = c,
                        _ => return Err(err("cell: expected one size in mm, 0 < size <= 0.25")),
                    }
                }
                "blank" | "pocket" => {
                    let blank = kw.eq_ignore_ascii_case("blank");
                    let w = if blank {
                        words(line, "blank", rest, "XYWHZB", "XYWHZ")?
                    } else {
                        words(line, "pocket", rest, "XYWHZ", "XYWHZ")?
                    };
                    if g(&w, 'W') <= 0.0 || g(&w, 'H') <= 0.0 {
                        return Err(err("width W and height H must be > 0 (inches)"));
                    }
                    if let Some(e) = envelope {
                        let (x, y, z) = (g(&w, 'X'), g(&w, 'Y'), g(&w, 'Z'));
                        e.check(line, &format!("{kw}: X"), 0, x)?;
                        e.check(line, &format!("{kw}: X + W"), 0, x + g(&w, 'W'))?;
                        e.check(line, &format!("{kw}: Y"), 1, y)?;
                        e.check(line, &format!("{kw}: Y + H"), 1, y + g(&w, 'H'))?;
                        let top = if blank { "top Z" } else { "floor Z" };
                        e.check(line, &format!("{kw}: {top}"), 2, z)?;
                    }
                    let (x, y) = (to_mm(g(&w, 'X')), to_mm(g(&w, 'Y')));
                    let r = [x, y, x + to_mm(g(&w, 'W')), y + to_mm(g(&w, 'H'))];
                    let z = to_mm(g(&w, 'Z'));
                    if blank {
                        let b = w[1].map(to_mm);
                        if b.is_some_and(|b| b >= z) {
                            return Err(err("blank: bottom B must be below the top Z"));
                        }
                        shapes.push((line, Shape::Blank { r, z, b }));
                    } else {
                        shapes.push((line, Shape::Pocket { r, z }));
                    }
                }
                "hole" => {
                    let w = words(line, "hole", rest, "XYDZ", "XYDZ")?;
                    if g(&w, 'D') <= 0.0 {
                        return Err(err("hole: diameter D must be > 0 (inches)"));
                    }
                    if let Some(e) = envelope {
                        let (x, y, r) = (g(&w, 'X'), g(&w, 'Y'), g(&w, 'D') / 2.0);
                        e.check(line, "hole: X - D/2", 0, x - r)?;
                        e.check(line, "hole: X + D/2", 0, x + r)?;
                        e.check(line, "hole: Y - D/2", 1, y - r)?;
                        e.check(line, "hole: Y + D/2", 1, y + r)?;
                        e.check(line, "hole: bottom Z", 2, g(&w, 'Z'))?;
                    }
                    shapes.push((
                        line,
                        Shape::Hole {
                            x: to_mm(g(&w, 'X')),
                            y: to_mm(g(&w, 'Y')),
                            d: to_mm(g(&w, 'D')),
                            z: to_mm(g(&w, 'Z')),
                        },
                    ));
                }
                other => {
                    return Err(err(&format!(
                        "unknown statement '{other}' (expected blank, hole, pocket or cell)"
                    )))
                }
            }
        }
        let mut bb = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut floor_mm = f64::INFINITY;
        let mut unbounded = false;
        for (_, s) in &shapes {
            if let Shape::Blank { r, b, .. } = s {
                bb = [
                    bb[0].min(r[0]),
                    bb[1].min(r[1]),
                    bb[2].max(r[2]),
                    bb[3].max(r[3]),
                ];
                match b {
                    Some(b) => floor_mm = floor_mm.min(*b),
                    None => unbounded = true,
                }
            }
        }
        if !bb[0].is_finite() {
            return Err(StockError {
                line: 0,
                msg: "no blank: at least one 'blank X.. Y.. W.. H.. Z..' line is needed".into(),
            });
        }
        if unbounded {
            floor_mm = f64::NEG_INFINITY;
        }
        let nx = ((bb[2] - bb[0]) / cell_mm).ceil() as usize;
        let ny = ((bb[3] - bb[1]) / cell_mm).ceil() as usize;
        if nx.saturating_mul(ny) > MAX_CELLS {
            return Err(StockError {
                line: 0,
                msg: format!("grid of {nx} x {ny} cells is larger than {MAX_CELLS} cells"),
            });
        }
        let mut st = Stock {
            x0_mm: bb[0],
            y0_mm: bb[1],
            cell_mm,
            nx,
            ny,
            top: vec![f64::NEG_INFINITY; nx * ny],
            floor_mm,
            odometer_mm: 0.0,
            lowered_at: vec![f64::NEG_INFINITY; nx * ny],
            max_top: Bound(f64::NEG_INFINITY),
        };
        for (_, s) in &shapes {
            match *s {
                Shape::Blank { r, z, .. } => st.apply(|x, y| in_rect(r, x, y), |t| t.max(z)),
                Shape::Pocket { r, z } => st.apply(|x, y| in_rect(r, x, y), |t| t.min(z)),
                Shape::Hole { x, y, d, z } => st.apply(
                    |cx, cy| (cx - x).powi(2) + (cy - y).powi(2) <= d * d / 4.0,
                    |t| t.min(z),
                ),
            }
        }
        st.max_top = highest(&st.top);
        Ok(st)
    }

    fn apply(&mut self, inside: impl Fn(f64, f64) -> bool, f: impl Fn(f64) -> f64) {
        for j in 0..self.ny {
            for i in 0..self.nx {
                let (x, y) = self.center(i, j);
                if inside(x, y) {
                    let k = j * self.nx + i;
                    self.top[k] = f(self.top[k]);
                }
            }
        }
    }

    /// The stock as it may be at worst (host: the optimiser's guard against a wrong
    /// description, issue 11): every cell of a blank filled to the stock's highest top, as if
    /// no hole, pocket or terrace had been made. Cells outside every blank stay empty.
    pub fn envelope(&self) -> Stock {
        let top = highest(&self.top).0;
        Stock {
            top: self
                .top
                .iter()
                .map(|&t| if t.is_finite() { top } else { t })
                .collect(),
            lowered_at: vec![f64::NEG_INFINITY; self.top.len()],
            max_top: Bound(top),
            ..self.clone()
        }
    }

    /// The material top of every cell (mm), row by row (cell (i, j) at `j * nx + i`, see
    /// [`Stock::dims`]), for comparing two cuts of the same stock.
    pub fn tops(&self) -> &[f64] {
        &self.top
    }

    fn center(&self, i: usize, j: usize) -> (f64, f64) {
        (
            self.x0_mm + (i as f64 + 0.5) * self.cell_mm,
            self.y0_mm + (j as f64 + 0.5) * self.cell_mm,
        )
    }

    /// Cell size, mm.
    pub fn cell_mm(&self) -> f64 {
        self.cell_mm
    }

    /// Grid size in cells (X, Y).
    pub fn dims(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    /// Lowest material Z (mm), `NEG_INFINITY` when no blank gives a bottom.
    pub fn floor_mm(&self) -> f64 {
        self.floor_mm
    }

    /// Material top (mm) of the cell containing (x, y) mm; `NEG_INFINITY` for air or outside.
    #[inline]
    pub fn top_at(&self, x_mm: f64, y_mm: f64) -> f64 {
        let fx = (x_mm - self.x0_mm) / self.cell_mm;
        let fy = (y_mm - self.y0_mm) / self.cell_mm;
        if fx < 0.0 || fy < 0.0 || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return f64::NEG_INFINITY;
        }
        self.top[fy as usize * self.nx + fx as usize]
    }

    /// Material top (mm) of the cell containing (x, y) mm when that cell's centre lies within
    /// `r_mm` of (cx, cy) (the cells [`Stock::cut_capsule`] would cut under a tool there),
    /// `NEG_INFINITY` otherwise, for air or outside.
    #[inline]
    pub fn top_in_disc(&self, x_mm: f64, y_mm: f64, cx: f64, cy: f64, r_mm: f64) -> f64 {
        let fx = (x_mm - self.x0_mm) / self.cell_mm;
        let fy = (y_mm - self.y0_mm) / self.cell_mm;
        if fx < 0.0 || fy < 0.0 || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return f64::NEG_INFINITY;
        }
        let (i, j) = (fx as usize, fy as usize);
        let (x, y) = self.center(i, j);
        let (px, py) = (cx - x, cy - y);
        if px * px + py * py > r_mm * r_mm {
            return f64::NEG_INFINITY;
        }
        self.top[j * self.nx + i]
    }

    /// [`Stock::top_in_disc`] and the squared distance (mm^2) of the cell's centre from
    /// (cx, cy) (infinite off the grid).
    #[inline]
    pub fn top_d2_in_disc(&self, x_mm: f64, y_mm: f64, cx: f64, cy: f64, r_mm: f64) -> (f64, f64) {
        let fx = (x_mm - self.x0_mm) / self.cell_mm;
        let fy = (y_mm - self.y0_mm) / self.cell_mm;
        if fx < 0.0 || fy < 0.0 || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return (f64::NEG_INFINITY, f64::INFINITY);
        }
        let (x, y) = self.center(fx as usize, fy as usize);
        let (px, py) = (cx - x, cy - y);
        let d2 = px * px + py * py;
        if d2 > r_mm * r_mm {
            return (f64::NEG_INFINITY, d2);
        }
        (self.top[fy as usize * self.nx + fx as usize], d2)
    }

    /// Which cells of the square of half-width `r_mm` around (cx, cy) hold material above `z`
    /// as [`Stock::top_in_disc`] reads them (their centre within `r_mm` of (cx, cy)): read once
    /// for a point, asked many times by [`Stock::above_in_disc`].
    pub fn disc_mask(&self, cx: f64, cy: f64, r_mm: f64, z: f64) -> DiscMask {
        let mask = DiscMask {
            i0: 0,
            j0: 0,
            w: 0,
            h: 0,
            bits: Vec::new(),
            cx,
            cy,
            r_mm,
            z,
        };
        // A square off the grid holds no cell: the empty mask, every question answered by
        // `top_in_disc` (NEG_INFINITY there).
        let Some((cols, rows)) = self.cells_near(cx, cy, r_mm) else {
            return mask;
        };
        let (i0, j0) = (*cols.start(), *rows.start());
        let (w, h) = (cols.clone().count(), rows.clone().count());
        let mut bits = vec![false; w * h];
        for j in rows {
            for i in cols.clone() {
                let (x, y) = self.center(i, j);
                let (px, py) = (cx - x, cy - y);
                bits[(j - j0) * w + (i - i0)] =
                    px * px + py * py <= r_mm * r_mm && self.top[j * self.nx + i] > z;
            }
        }
        DiscMask {
            i0,
            j0,
            w,
            h,
            bits,
            ..mask
        }
    }

    /// `top_in_disc(x, y, cx, cy, r_mm) > z` for the mask's disc and height, from the mask.
    #[inline]
    pub fn above_in_disc(&self, m: &DiscMask, x_mm: f64, y_mm: f64) -> bool {
        let fx = (x_mm - self.x0_mm) / self.cell_mm;
        let fy = (y_mm - self.y0_mm) / self.cell_mm;
        if fx < 0.0 || fy < 0.0 || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return false;
        }
        let (i, j) = (fx as usize, fy as usize);
        if i < m.i0 || j < m.j0 || i - m.i0 >= m.w || j - m.j0 >= m.h {
            return self.top_in_disc(x_mm, y_mm, m.cx, m.cy, m.r_mm) > m.z;
        }
        m.bits[(j - m.j0) * m.w + (i - m.i0)]
    }

    /// No cell's top is above this (mm): the highest top when the stock was made (cuts only
    /// lower cells).
    pub fn max_top(&self) -> f64 {
        self.max_top.0
    }

    /// The highest top (mm) of the cells that hold a point of the square of half-width `half`
    /// (mm) around (x, y) (`NEG_INFINITY` where all of it is air or outside the grid).
    pub fn max_top_near(&self, x_mm: f64, y_mm: f64, half: f64) -> f64 {
        let Some((cols, rows)) = self.cells_near(x_mm, y_mm, half) else {
            return f64::NEG_INFINITY;
        };
        let mut top = f64::NEG_INFINITY;
        for j in rows {
            let row = &self.top[j * self.nx + cols.start()..=j * self.nx + cols.end()];
            top = row.iter().fold(top, |m, &t| if t > m { t } else { m });
        }
        top
    }

    /// The columns and rows of the cells that hold a point of the square of half-width `half`
    /// (mm) around (x, y); None when the square misses the grid.
    fn cells_near(&self, x_mm: f64, y_mm: f64, half: f64) -> Option<(Cells, Cells)> {
        let (fx0, fx1) = (x_mm - half - self.x0_mm, x_mm + half - self.x0_mm);
        let (fy0, fy1) = (y_mm - half - self.y0_mm, y_mm + half - self.y0_mm);
        let (w, h) = (self.nx as f64 * self.cell_mm, self.ny as f64 * self.cell_mm);
        if fx1 < 0.0 || fy1 < 0.0 || fx0 >= w || fy0 >= h {
            return None;
        }
        let idx = |f: f64, n: usize| (f / self.cell_mm).floor().clamp(0.0, n as f64 - 1.0) as usize;
        Some((
            idx(fx0, self.nx)..=idx(fx1, self.nx),
            idx(fy0, self.ny)..=idx(fy1, self.ny),
        ))
    }

    /// The XY path length the tool has swept over this stock, mm (see the module docs).
    pub fn odometer_mm(&self) -> f64 {
        self.odometer_mm
    }

    /// The cell containing (x, y) mm for a tool whose bottom is at `base_mm`: material above
    /// it, air the tool made at odometer `recent_mm` or later, or older air (also outside).
    #[inline]
    pub(crate) fn cell_class(&self, k: Option<usize>, base_mm: f64, recent_mm: f64) -> Cell {
        match k {
            Some(k) if self.top[k] > base_mm => Cell::Material,
            Some(k) if self.lowered_at[k] >= recent_mm => Cell::Recent,
            _ => Cell::Old,
        }
    }

    /// Walks the cells a segment crosses: from (x, y) mm along the unit XY direction `d` for
    /// `len_mm`, calling `f(t, cell)` with the distance along the segment at which each cell is
    /// entered (0 for the first) and its index (None outside the grid, where the walk ends), in
    /// order, until `f` returns false.
    pub(crate) fn walk(
        &self,
        p: [f64; 2],
        d: [f64; 2],
        len_mm: f64,
        mut f: impl FnMut(f64, Option<usize>) -> bool,
    ) {
        let fx = (p[0] - self.x0_mm) / self.cell_mm;
        let fy = (p[1] - self.y0_mm) / self.cell_mm;
        let (mut i, mut j) = (fx.floor(), fy.floor());
        let axis = |f: f64, i: f64, d: f64| {
            if d > 0.0 {
                (((i + 1.0) - f) * self.cell_mm / d, self.cell_mm / d, 1.0)
            } else if d < 0.0 {
                ((f - i) * self.cell_mm / -d, self.cell_mm / -d, -1.0)
            } else {
                (f64::INFINITY, f64::INFINITY, 0.0)
            }
        };
        let (mut tx, dtx, si) = axis(fx, i, d[0]);
        let (mut ty, dty, sj) = axis(fy, j, d[1]);
        let mut t = 0.0;
        loop {
            let inside = i >= 0.0 && j >= 0.0 && i < self.nx as f64 && j < self.ny as f64;
            let k = inside.then(|| j as usize * self.nx + i as usize);
            if !f(t, k) || k.is_none() {
                return;
            }
            if tx < ty {
                t = tx;
                tx += dtx;
                i += si;
            } else {
                t = ty;
                ty += dty;
                j += sj;
            }
            if t > len_mm {
                return;
            }
        }
    }

    /// Volume of material above `z_ref_mm` (mm^3), for tests and reports.
    pub fn volume_above_mm3(&self, z_ref_mm: f64) -> f64 {
        let a = self.cell_mm * self.cell_mm;
        self.top.iter().map(|&t| (t - z_ref_mm).max(0.0) * a).sum()
    }

    /// Removes the material swept by a disc of radius `r_mm` whose centre moves along the segment
    /// from `a` to `b` (mm; the tool tip Z interpolated along it): every cell whose centre lies
    /// within `r_mm` of the segment gets `top = min(top, tip Z at the nearest segment point)`;
    /// a cell so lowered remembers the odometer at that point, and the odometer advances by the
    /// segment's XY length.
    pub fn cut_capsule(&mut self, a: [f64; 3], b: [f64; 3], r_mm: f64) {
        self.cut_swept::<false>(a, b, r_mm, |_| 0.0);
    }

    /// [`Stock::cut_capsule`] by a tool of `shape` (its radius `r_mm`): a cell at distance `d`
    /// from the segment is lowered to the tip Z there plus the edge's height above the tip at
    /// `d` ([`crate::Shape::lift_mm`]): the ball's sphere, the drill's cone. The nearest point
    /// of the segment gives the height (exact for a level segment; the process's segments are
    /// one sample's motion, micrometres). A flat end mill: the same bytes as `cut_capsule`.
    pub fn cut_shaped(&mut self, a: [f64; 3], b: [f64; 3], r_mm: f64, shape: crate::Shape) {
        match shape {
            crate::Shape::Flat => self.cut_capsule(a, b, r_mm),
            _ => self.cut_swept::<true>(a, b, r_mm, |d2| shape.lift_mm(r_mm, d2.sqrt())),
        }
    }

    /// The cut of [`Stock::cut_shaped`], the edge's height above the tip from the squared
    /// distance (mm^2; never negative; not asked unless `SHAPED`).
    #[inline(always)]
    fn cut_swept<const SHAPED: bool>(
        &mut self,
        a: [f64; 3],
        b: [f64; 3],
        r_mm: f64,
        lift: impl Fn(f64) -> f64,
    ) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let odo = self.odometer_mm;
        let len = len2.sqrt();
        self.odometer_mm += len;
        // Cells this cut cannot lower are skipped before the distance test (the same cells are
        // lowered to the same bytes): a cell whose top is at or below `z_lo`, a bound of the
        // tip Z at every point of the segment (a level segment or a plunge: exactly its Z;
        // otherwise the lower end less far more than the rounding of the interpolation); all of
        // them when the tip stays at or above the highest top (a move in the air).
        let z_lo = if a[2] == b[2] || len2 == 0.0 {
            a[2]
        } else {
            a[2].min(b[2]) - (a[2].abs() + b[2].abs()) * 1e-9
        };
        if z_lo >= self.max_top.0 {
            return;
        }
        let lo = |v: f64, o: f64| ((v - o) / self.cell_mm).floor();
        let i0 = lo(a[0].min(b[0]) - r_mm, self.x0_mm).max(0.0);
        let i1 = lo(a[0].max(b[0]) + r_mm, self.x0_mm).min(self.nx as f64 - 1.0);
        let j0 = lo(a[1].min(b[1]) - r_mm, self.y0_mm).max(0.0);
        let j1 = lo(a[1].max(b[1]) + r_mm, self.y0_mm).min(self.ny as f64 - 1.0);
        if !(i0 <= i1 && j0 <= j1) {
            return;
        }
        let r2 = r_mm * r_mm;
        // And in each row the cells whose centres lie farther along X than `r_mm` (and a margin)
        // from the segment's X extent at the nearest Y.
        let (xa, xb) = (a[0].min(b[0]), a[0].max(b[0]));
        let (ya, yb) = (a[1].min(b[1]), a[1].max(b[1]));
        for j in j0 as usize..=j1 as usize {
            let (_, y) = self.center(0, j);
            let gap = (ya - y).max(y - yb).max(0.0);
            let h = (r2 - gap * gap).max(0.0).sqrt() + 1e-6;
            let ia = ((xa - h - self.x0_mm) / self.cell_mm - 0.5).floor().max(i0);
            let ib = ((xb + h - self.x0_mm) / self.cell_mm - 0.5).ceil().min(i1);
            if ia > ib {
                continue;
            }
            let row = j * self.nx;
            let (ia, ib) = (ia as usize, ib as usize);
            // Eight cells at a time passed over where none is above `z_lo` (most of a disc the
            // tool has already cut): one comparison the compiler unrolls, not eight branches.
            let mut chunk = ia;
            while chunk <= ib {
                let end = (chunk + 8).min(ib + 1);
                let first = chunk;
                chunk = end;
                let above = self.top[row + first..row + end]
                    .iter()
                    .fold(false, |any, &t| any | (t > z_lo));
                if !above {
                    continue;
                }
                for i in first..end {
                    if self.top[row + i] <= z_lo {
                        continue;
                    }
                    let (x, y) = self.center(i, j);
                    let s = if len2 > 0.0 {
                        (((x - a[0]) * dx + (y - a[1]) * dy) / len2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let (px, py) = (a[0] + s * dx - x, a[1] + s * dy - y);
                    let d2 = px * px + py * py;
                    if d2 <= r2 {
                        let z = a[2] + s * (b[2] - a[2]);
                        let z = if SHAPED { z + lift(d2) } else { z };
                        let k = j * self.nx + i;
                        if z < self.top[k] {
                            self.top[k] = z;
                            self.lowered_at[k] = odo + s * len;
                        }
                    }
                }
            }
        }
    }
}

fn in_rect(r: [f64; 4], x: f64, y: f64) -> bool {
    x >= r[0] && x < r[2] && y >= r[1] && y < r[3]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Stock::cut_capsule`] testing every cell of the segment's bounding box (as it did before
    /// it skipped the cells it cannot lower).
    fn cut_capsule_every_cell(st: &mut Stock, a: [f64; 3], b: [f64; 3], r_mm: f64) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let odo = st.odometer_mm;
        let len = len2.sqrt();
        st.odometer_mm += len;
        let lo = |v: f64, o: f64| ((v - o) / st.cell_mm).floor();
        let i0 = lo(a[0].min(b[0]) - r_mm, st.x0_mm).max(0.0);
        let i1 = lo(a[0].max(b[0]) + r_mm, st.x0_mm).min(st.nx as f64 - 1.0);
        let j0 = lo(a[1].min(b[1]) - r_mm, st.y0_mm).max(0.0);
        let j1 = lo(a[1].max(b[1]) + r_mm, st.y0_mm).min(st.ny as f64 - 1.0);
        if !(i0 <= i1 && j0 <= j1) {
            return;
        }
        let r2 = r_mm * r_mm;
        for j in j0 as usize..=j1 as usize {
            for i in i0 as usize..=i1 as usize {
                let (x, y) = st.center(i, j);
                let s = if len2 > 0.0 {
                    (((x - a[0]) * dx + (y - a[1]) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (px, py) = (a[0] + s * dx - x, a[1] + s * dy - y);
                if px * px + py * py <= r2 {
                    let z = a[2] + s * (b[2] - a[2]);
                    let k = j * st.nx + i;
                    if z < st.top[k] {
                        st.top[k] = z;
                        st.lowered_at[k] = odo + s * len;
                    }
                }
            }
        }
    }

    /// The cut skips only cells it cannot lower: the same tops and the same memory, bit for bit,
    /// as testing every cell, along a random walk of short and long segments (level, plunging,
    /// rising, ramping, standing still, partly off the grid) with tool radii on and off the cells.
    #[test]
    fn the_cut_lowers_the_cells_testing_every_cell_would() {
        let mut fast = Stock::default();
        let mut every = fast.clone();
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut a = [30.0, 40.0, -1.0];
        for n in 0..3000 {
            let step = if n % 7 == 0 { 8.0 } else { 0.3 };
            let mut b = [
                a[0] + (rnd() - 0.5) * step,
                a[1] + (rnd() - 0.5) * step,
                a[2],
            ];
            match n % 5 {
                0 => b[2] = a[2] - rnd() * 0.2,
                1 => b[2] = a[2] + rnd() * 0.1,
                2 => b = [a[0], a[1], a[2] - 0.05],
                3 if n % 3 == 0 => b = a,
                _ => {}
            }
            b[0] = b[0].clamp(-10.0, 140.0);
            b[1] = b[1].clamp(-10.0, 90.0);
            b[2] = b[2].clamp(-15.0, 1.0);
            let r = [6.35, 3.0, 0.125, 1.6][n % 4];
            fast.cut_capsule(a, b, r);
            cut_capsule_every_cell(&mut every, a, b, r);
            a = b;
        }
        // Moves in the air (at the highest top, and above it) lower nothing either way and
        // advance the odometer alike; one just below it cuts.
        let top = highest(&fast.top).0;
        for (a, b) in [
            ([20.0, 20.0, top], [60.0, 50.0, top]),
            ([0.0, 0.0, top + 5.0], [100.0, 80.0, top + 2.0]),
            ([10.0, 70.0, top - 0.01], [12.0, 70.0, top - 0.01]),
        ] {
            fast.cut_capsule(a, b, 6.35);
            cut_capsule_every_cell(&mut every, a, b, 6.35);
        }
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&fast.top), bits(&every.top));
        assert_eq!(bits(&fast.lowered_at), bits(&every.lowered_at));
        assert_eq!(fast.odometer_mm.to_bits(), every.odometer_mm.to_bits());
        assert!(fast.volume_above_mm3(-20.0) < Stock::default().volume_above_mm3(-20.0));
    }

    const TRAVEL: Envelope = Envelope {
        min_in: [-10.0, -10.0, -4.0],
        max_in: [10.0, 10.0, 4.0],
    };

    /// A stock outside the envelope is refused with its line and what lies where; the default
    /// stock and a stock at the envelope's edges are taken. Without an envelope `parse` takes
    /// any finite size, as before.
    #[test]
    fn a_stock_outside_the_envelope_is_refused_with_its_line() {
        for (src, line, what) in [
            (
                "blank X0 Y0 W5 H3 Z1e6\n",
                1,
                "blank: top Z at 1000000 in lies outside the Z range -4..4 in",
            ),
            (
                "# c\nblank X0 Y0 W50 H3 Z0\n",
                2,
                "blank: X + W at 50 in lies outside the X range -10..10 in",
            ),
            (
                "blank X0 Y0 W5 H3 Z0\npocket X1 Y1 W1 H1 Z-9\n",
                2,
                "pocket: floor Z",
            ),
            (
                "blank X0 Y0 W5 H3 Z0\nhole X1 Y9.9 D0.5 Z-1\n",
                2,
                "hole: Y + D/2",
            ),
        ] {
            let e = Stock::parse_within(src, &TRAVEL).unwrap_err();
            assert_eq!(e.line, line, "{src}: {e}");
            assert!(e.msg.contains(what), "{src}: {e}");
            assert!(Stock::parse(src).is_ok(), "{src}");
        }
        assert!(Stock::parse_within(FIG1_STOCK, &TRAVEL).is_ok());
        assert!(Stock::parse_within("blank X-10 Y-10 W20 H20 Z4 B-30\n", &TRAVEL).is_ok());
    }
}
