//! The adaptive loop natively on the host (host): the firmware's frame and pulse-end ISR bodies on
//! the host board ([`crate::host::board`]), the firmware's sampler and AC-period bodies (`millac::rt::ac`, with the same
//! `AcController`) over a host ADC port, and the simulated cutting process (`millac-plant`), on one
//! virtual clock with the firmware's timing (frames at W0 or the rapid rate in the QEMU board's
//! timer clocks, ADC samples at `sample_hz` from the pulses emitted so far, an AC period every
//! `sample_hz * period_ms / 1000` samples). For fast experiments and benchmarks; the QEMU run is
//! the reference for the firmware itself.
use crate::analysis::ProgBlock;
use crate::host::board::HostFrames;
use anyhow::{anyhow, Result};
use millac::ac::{AcController, AcSettings, AcState};
use millac::gcode::tape::finish_block;
use millac::nc::{Block, FrameConfig, Motion, Rate, Sealed};
use millac::ports::{Conversion, ForceTorqueAdc};
use millac::rt::ac::{self as rt_ac, AcPeriod};
use millac::rt::replan::{Event as ReplanEvent, HostQueue, Replan, Replanned, SpeedChange};
use millac::rt::status::SamplerWriter;
use millac::rt::Status;
use millac::Settings;
use millac_plant::{Damage, Material, Process, Stock, Tool, ToothEvent, Transducer};
use std::collections::VecDeque;

/// One AC period of a run: what the controller saw and did, and what really happened.
#[derive(Clone, Debug, PartialEq)]
pub struct AcRow {
    pub t_ms: u64,
    pub pos_blu: [i64; 3],
    /// Path speed over the period, from the pulses (ipm).
    pub feed_ipm: f64,
    pub f_meas_n: f64,
    pub t_meas_nm: f64,
    /// Peaks of the true force and torque over the period's samples.
    pub f_true_n: f64,
    pub t_true_nm: f64,
    pub e: f64,
    pub state: String,
    /// The controller's feed number, as the firmware logs it (u32::MAX = no AC): the cap the
    /// frame reads, or under the plan (`FeedCeiling::Plan`) k x f_max.
    pub feed_cap: u32,
    /// The feed law's estimates after the period (`AcController::law_estimates`: GPC's
    /// [a1, a2, b0, b1, b2], MRAC's [p^, b^, 0, 0, 0]); None for the fixed laws, without AC and
    /// in the QEMU runs' rows (the firmware does not log them).
    pub estimates: Option<[f32; 5]>,
    /// The tool in the spindle (the last M6's T; 0: none fitted, the cut's tool).
    pub tool: u8,
}

/// The process set-up of a run.
#[derive(Clone, Debug)]
pub struct Cut {
    pub stock: Stock,
    pub tool: Tool,
    pub material: Material,
    pub spindle_rpm: f64,
    pub seed: u64,
    pub transducer: Transducer,
    /// The feed drives (`--drive`): a stepper (the tool where the pulses put it) or the thesis'
    /// servo position loop.
    pub drive: millac_plant::DriveModel,
    /// Radial run-out per tooth, mm (`--runout`; empty = none): `millac_plant::teeth`.
    pub runout_mm: Vec<f64>,
    /// Chipped and broken teeth from given times (`--chip-tooth`, `--break-tooth`).
    pub tooth_events: Vec<ToothEvent>,
    /// The tool's modes in X and Y (a flexible tool that can chatter, heard by the microphone at
    /// [`SOUND_HZ`]; `--preset thesis-table-3.2`); None: a rigid tool, no sound.
    pub modes: Option<(
        Vec<millac_plant::lobes::Mode>,
        Vec<millac_plant::lobes::Mode>,
    )>,
    /// The program's tool changes ([`Cut::with_tool_changes`]; empty: one tool, `tool`, for
    /// the whole program), and the machine's tool table they came from (a QEMU run's firmware
    /// gets it in its settings record).
    pub changes: Vec<ToolChangeAt>,
    pub tools: millac::gcode::tools::ToolTable,
}

/// A tool change of a program (M6) as a host run makes it: once the blocks before it have run
/// and the machine stands (the firmware's loader runs an M6 so), the AC task, the sampler and the
/// monitors get `fitted` through the status words, as from the firmware's loader; the process
/// cuts on with `plant` at `rpm`, the stock as the tool before left it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolChangeAt {
    /// The blocks that run before it.
    pub at_block: usize,
    /// Its line in the program.
    pub line: u32,
    pub fitted: millac::rt::status::FittedTool,
    /// The plant's tool: the table entry's diameter and flutes, its limits (the torque no higher
    /// than the cut's tool's: the drive's); the cut's `tool` where the entry has no diameter.
    pub plant: Tool,
    /// The spindle speed of its part of the program (the last S before the next change).
    pub rpm: f64,
}

/// The sound channel's sample rate of a flexible tool's microphone, Hz (the chatter detector's
/// default, `millac::monitor::chatter::ChatterSettings::sound_hz`).
pub const SOUND_HZ: f64 = 5000.0;

impl Cut {
    /// The experiments' usual cut: `stock` in steel with the default tool at the paper's 600 rpm,
    /// the default transducer with noise seed `seed`, stepper drives.
    pub fn steel(stock: Stock, seed: u64) -> Cut {
        Cut {
            stock,
            tool: Tool::default(),
            material: Material::STEEL,
            spindle_rpm: millac_plant::DEFAULT_RPM,
            seed,
            transducer: Transducer::default(),
            drive: millac_plant::DriveModel::Stepper,
            runout_mm: Vec::new(),
            modes: None,
            tooth_events: Vec::new(),
            changes: Vec::new(),
            tools: Default::default(),
        }
    }

    /// This cut at the spindle speed the program `text` sets (its last S word, read by the
    /// firmware's tape: [`crate::analysis::spindle_rpm`]), or at the plant's default
    /// [`millac_plant::DEFAULT_RPM`] (600) when it sets none. Every command that knows its program
    /// before the run (`run`, `demo`, `host`, the benchmark examples) builds its cut with it.
    pub fn at_program_rpm(self, text: &str, settings: &Settings) -> Cut {
        Cut {
            spindle_rpm: program_rpm(text, settings),
            ..self
        }
    }

    /// This cut following the tool changes of program `text` (its M6s) on a machine whose tool
    /// table is `tools` (the operator's `$T` lines; a G10 L1 in the program changes it as it
    /// goes): each tool's part of the program at its own spindle speed, and the part before the
    /// first change at the S set before it (else the cut's). A program without M6 is cut as it
    /// was (the same bytes).
    pub fn with_tool_changes(
        mut self,
        text: &str,
        settings: &Settings,
        tools: &millac::gcode::tools::ToolTable,
    ) -> Cut {
        self.tools = *tools;
        let r = crate::analysis::read_lines_with(text.as_bytes(), settings, tools);
        // The S in force just before line `before` (0: none yet).
        let rpm_before = |before: u32| {
            r.spindle
                .iter()
                .take_while(|(l, _)| *l < before)
                .last()
                .map_or(0, |s| s.1)
        };
        let Some(first) = r.tool_changes.first() else {
            return self;
        };
        if let rpm @ 1.. = rpm_before(first.line) {
            self.spindle_rpm = f64::from(rpm);
        }
        let mut rpm = self.spindle_rpm;
        self.changes = r
            .tool_changes
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let next = r.tool_changes.get(i + 1).map_or(u32::MAX, |n| n.line);
                if let s @ 1.. = rpm_before(next) {
                    rpm = f64::from(s);
                }
                let fitted = millac::rt::status::FittedTool::of(c.tool, c.entry.as_ref());
                ToolChangeAt {
                    at_block: c.after_blocks,
                    line: c.line,
                    fitted,
                    plant: self.plant_tool(&fitted, c.entry.as_ref()),
                    rpm,
                }
            })
            .collect();
        self
    }

    /// The tool's part of the program block `i` belongs to: 0 before the first change, k after
    /// the k-th.
    pub fn part_of(&self, i: usize) -> usize {
        self.changes.partition_point(|c| c.at_block <= i)
    }

    /// The plant's tool for a fitted tool (see [`ToolChangeAt::plant`]).
    fn plant_tool(
        &self,
        fitted: &millac::rt::status::FittedTool,
        entry: Option<&millac::gcode::tools::Tool>,
    ) -> Tool {
        let Some(e) = entry.filter(|e| e.diameter_pm > 0) else {
            return self.tool;
        };
        let limits = fitted.limits;
        Tool {
            diameter_mm: e.diameter_pm as f64 * 1e-9,
            flutes: fitted.flutes_or(self.tool.flutes),
            f_max_n: limits.map_or(self.tool.f_max_n, |l| f64::from(l.force_n)),
            t_max_nm: limits.map_or(self.tool.t_max_nm, |l| {
                f64::from(l.torque_nm).min(self.tool.t_max_nm)
            }),
            shape: plant_shape(e.kind),
        }
    }

    /// The process of this cut (checked: the plant's errors, e.g. a tooth the tool does not
    /// have).
    pub fn process(&self) -> Result<Process> {
        let mut p = Process::new(
            self.stock.clone(),
            self.tool,
            self.material,
            self.spindle_rpm,
            self.seed,
            self.transducer,
        )
        .map(|p| p.with_drive(self.drive))
        .map_err(|e| anyhow!("{}", e.0))?;
        if let Some((x, y)) = &self.modes {
            p = p
                .with_tool_modes(
                    x,
                    y,
                    millac_plant::chatter::Microphone::default(),
                    SOUND_HZ,
                    self.seed ^ 0x50_55_4e_44,
                )
                .map_err(|e| anyhow!("tool modes: {}", e.0))?;
        }
        if !self.runout_mm.is_empty() {
            p = p
                .with_runout(&self.runout_mm)
                .map_err(|e| anyhow!("--runout: {}", e.0))?;
        }
        for ev in &self.tooth_events {
            p = p.with_tooth_event(*ev).map_err(|e| {
                let opt = match ev.damage {
                    Damage::Broken => "--break-tooth",
                    Damage::Chipped { .. } => "--chip-tooth",
                };
                anyhow!("{opt}: {}", e.0)
            })?;
        }
        Ok(p)
    }
}

/// `--break-tooth N@SECONDS`: tooth N (from 0, in cutting order) breaks at SECONDS of virtual
/// time. The tooth's range is checked against the tool by [`Cut::process`].
/// The plant's shape of a tool table's kind (`$T` K): a drill with the usual 118 degree point.
pub fn plant_shape(kind: millac::gcode::tools::ToolKind) -> millac_plant::Shape {
    use millac::gcode::tools::ToolKind;
    use millac_plant::Shape;
    match kind {
        ToolKind::Flat => Shape::Flat,
        ToolKind::Ball => Shape::Ball,
        ToolKind::Drill => Shape::Drill {
            point_deg: Shape::DRILL_POINT_DEG,
        },
    }
}

pub fn parse_break_tooth(s: &str) -> std::result::Result<ToothEvent, String> {
    let (tooth, t_s) = tooth_at(s, "N@SECONDS, e.g. 1@2.5")?;
    Ok(ToothEvent {
        tooth,
        t_s,
        damage: Damage::Broken,
    })
}

/// `--chip-tooth N@SECONDS[:DEPTH_MM]`: tooth N's edge loses DEPTH_MM of radius at SECONDS
/// (default depth [`millac_plant::teeth::DEFAULT_CHIP_MM`], 0.05 mm).
pub fn parse_chip_tooth(s: &str) -> std::result::Result<ToothEvent, String> {
    let form = "N@SECONDS[:DEPTH_MM], e.g. 1@2.5:0.05";
    let (at, depth) = match s.split_once(':') {
        Some((at, d)) => (
            at,
            d.parse::<f64>()
                .map_err(|_| format!("`{s}`: `{d}` is not a depth in mm ({form})"))?,
        ),
        None => (s, millac_plant::teeth::DEFAULT_CHIP_MM),
    };
    let (tooth, t_s) = tooth_at(at, form)?;
    if !(depth.is_finite() && depth >= 0.0) {
        return Err(format!("`{s}`: the depth must be finite and >= 0 mm"));
    }
    Ok(ToothEvent {
        tooth,
        t_s,
        damage: Damage::Chipped { depth_mm: depth },
    })
}

/// `N@SECONDS` of the tooth options.
fn tooth_at(s: &str, form: &str) -> std::result::Result<(u32, f64), String> {
    let (n, t) = s
        .split_once('@')
        .ok_or_else(|| format!("`{s}`: expected {form}"))?;
    let tooth: u32 = n
        .parse()
        .map_err(|_| format!("`{s}`: `{n}` is not a tooth number (0, 1, ...; {form})"))?;
    let t_s: f64 = t
        .parse()
        .map_err(|_| format!("`{s}`: `{t}` is not a time in seconds ({form})"))?;
    if !(t_s.is_finite() && t_s >= 0.0) {
        return Err(format!("`{s}`: the time must be finite and >= 0 s"));
    }
    Ok((tooth, t_s))
}

/// `--runout UM,UM,...`: radial run-out per tooth in micrometres (one value per tooth, in
/// cutting order from tooth 0; signed: + cuts deeper), as mm. The count is checked against the
/// tool by [`Cut::process`].
#[derive(Clone, Debug, PartialEq)]
pub struct RunoutUm(pub Vec<f64>);

impl std::str::FromStr for RunoutUm {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<RunoutUm, String> {
        s.split(',')
            .map(|v| {
                let um: f64 = v.trim().parse().map_err(|_| {
                    format!(
                        "`{s}`: `{v}` is not a run-out in micrometres (UM,UM,..., e.g. 10,0,0,0)"
                    )
                })?;
                if !um.is_finite() {
                    return Err(format!("`{s}`: the run-out must be finite"));
                }
                Ok(um / 1000.0)
            })
            .collect::<std::result::Result<Vec<f64>, String>>()
            .map(RunoutUm)
    }
}

/// The simulated spindle speed of a program: its last S word, or [`millac_plant::DEFAULT_RPM`]
/// without one.
pub fn program_rpm(text: &str, settings: &Settings) -> f64 {
    match crate::analysis::spindle_rpm(text, settings) {
        0 => millac_plant::DEFAULT_RPM,
        rpm => f64::from(rpm),
    }
}

/// The machine's travel in inches (the default settings' soft limits), the space a stock file
/// must lie in ([`load_stock`]).
pub fn travel() -> millac_plant::Envelope {
    let s = Settings::default();
    let (num, den) = s.blu.per_inch();
    let inch = |blu: i32| f64::from(blu) * den as f64 / num as f64;
    millac_plant::Envelope {
        min_in: s.soft_min.map(inch),
        max_in: s.soft_max.map(inch),
    }
}

/// A stock description file (`--stock`), refused with its path and line when it does not parse
/// or reaches outside the machine's travel ([`travel`]: a height or size no machine here has,
/// e.g. `Z1e6`, which would otherwise simulate a cut kilometres deep for hours).
pub fn load_stock(path: &std::path::Path) -> Result<Stock> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("reading the stock file {}: {e}", path.display()))?;
    parse_stock(&text, &path.display().to_string())
}

/// A stock description's `text` (see [`load_stock`]); `origin` names it in an error.
pub fn parse_stock(text: &str, origin: &str) -> Result<Stock> {
    Stock::parse_within(text, &travel()).map_err(|e| {
        anyhow!("{origin}: {e}; a stock lies within the machine's travel (its soft limits)")
    })
}

/// A tool table file (`--tools`): `$T` lines as an operator types them at the console, each set
/// as the firmware's protocol sets it (`millac::protocol::table::MachineSettings::tool_line`);
/// blank lines and lines starting with `#` are skipped. A line the firmware would refuse is
/// refused with its path, line and grbl error.
pub fn load_tools(path: &std::path::Path) -> Result<millac::gcode::tools::ToolTable> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("reading the tool table {}: {e}", path.display()))?;
    parse_tools(&text, &path.display().to_string())
}

/// A tool table's `text` (see [`load_tools`]); `origin` names it in an error.
pub fn parse_tools(text: &str, origin: &str) -> Result<millac::gcode::tools::ToolTable> {
    let mut table = millac::protocol::table::MachineSettings::default();
    for (n, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        table.tool_line(l).map_err(|code| {
            anyhow!(
                "{origin} line {}: `{l}` refused with error:{code} (a $T line: $T<1-16>=L D N K F M)",
                n + 1
            )
        })?;
    }
    Ok(table.work.tools)
}

/// Result of a host run.
#[derive(Clone, Debug, Default)]
pub struct HostRun {
    pub rows: Vec<AcRow>,
    /// True force and torque of every ADC sample ([`Record::samples`]).
    pub samples: Vec<(f64, f64)>,
    /// The load figures over every ADC sample, against [`Record::load_fraction`] x F_max, and
    /// the number of samples.
    pub load: LoadFigures,
    pub sample_count: usize,
    /// The codes [T, Fu, Fv] the controller got at every sample (None: a missed conversion).
    pub codes: Vec<Option<[u16; 3]>>,
    /// Virtual time from the first to the last pulse (s).
    pub machining_time_s: f64,
    pub final_position: [i64; 3],
    /// Position after every frame that pulsed, with the programmed feed (ipm) and the block index
    /// ([`Record::path`]).
    pub path: Vec<([i64; 3], f64, usize)>,
    pub held: bool,
    /// The alarm that first held the feed (None: no hold); its text is what the firmware prints
    /// (`alarm: ...`).
    pub alarm: Option<millac::ac::Alarm>,
    /// Blocks completed when the run ended (the program's length when it finished).
    pub blocks_done: usize,
    /// Per block: (index, first frame start, last frame end) in ns of virtual time.
    pub spans: Vec<(usize, u64, u64)>,
    /// The chatter monitor's spectrum of every sound record, with the time it ended (s).
    pub spectra: Vec<(f64, millac::monitor::chatter::Spectrum)>,
    /// Chatter suppression's re-plans and refusals (`millac::rt::replan`, the loader's code),
    /// with their virtual time (s).
    pub replans: Vec<(f64, Replanned)>,
    pub refused: Vec<(f64, millac::rt::replan::Refusal)>,
    /// The spindle speed changes of the chatter reaction (`$277`), applied to the process.
    pub speeds: Vec<(f64, SpeedChange)>,
    /// The stock as the run left it (the plant's height map).
    pub stock: Option<Stock>,
    /// A multi-tool run's stock as each tool left it (its number; the last is the run's end).
    pub stocks: Vec<(u8, Stock)>,
    /// Virtual time (ns) at which the AC first held the feed (the frame's cap went to 0: the
    /// sampler's trip or the AC period), and of the last pulse of the run.
    pub hold_ns: Option<u64>,
    pub last_pulse_ns: u64,
    /// The run was cut short by the host tool's SIGINT or SIGTERM ([`crate::interrupt`]): what
    /// ran until then.
    pub interrupted: bool,
    /// Each tool's part of the run ([`Cut::changes`]), in order: the part before the first
    /// change (tool 0, the cut's tool) when blocks ran in it, then one per change made.
    pub tools: Vec<ToolRun>,
}

/// The tool cutting in a host run, until the next change.
#[derive(Default)]
struct ToolPart {
    tool: u8,
    /// 0 before the first change, k after the k-th.
    part: usize,
    from_block: usize,
    start_ns: u64,
    limited: bool,
    alarm: Option<millac::ac::Alarm>,
    /// AC periods in the cut, and those of them slower than programmed; the lowest feed in
    /// the cut; the holds entered; whether the period before was held.
    cutting: u32,
    controlled: u32,
    lowest_ipm: Option<f64>,
    holds: u32,
    was_held: bool,
}

/// A period is in the cut when its highest true force or torque is above this share of the
/// tool's F_max or T_max (the AFC log's cutting time; air and a tooth's graze are not; a drill
/// loads its torque, hardly its radial force).
pub const CUTTING_SHARE: f64 = 0.05;

impl ToolPart {
    /// One AC period's figures: its highest true force (N) and torque (N m), the feed achieved
    /// and programmed (ipm), whether it held; the tool.
    fn period(&mut self, peak: (f64, f64), feed: f64, programmed: f64, held: bool, tool: &Tool) {
        self.holds += u32::from(held && !self.was_held);
        self.was_held = held;
        if peak.0 > CUTTING_SHARE * tool.f_max_n || peak.1 > CUTTING_SHARE * tool.t_max_nm {
            self.cutting += 1;
            // Slower than programmed by more than the frame's own quantisation (a feed number).
            self.controlled += u32::from(feed < 0.98 * programmed || held);
            self.lowest_ipm = Some(self.lowest_ipm.map_or(feed, |l| l.min(feed)));
        }
    }

    /// Its part, ended at `t` (ns) with `blocks` done, its samples tallied in `tally`; none for
    /// the part before the first change when it ran no block.
    fn end(self, t: u64, blocks: usize, tally: &LoadTally, period_ms: u32) -> Option<ToolRun> {
        (self.tool != 0 || blocks > 0).then(|| ToolRun {
            tool: self.tool,
            part: self.part,
            from_block: self.from_block,
            blocks: blocks - self.from_block,
            start_ns: self.start_ns,
            end_ns: t,
            load: tally.figures(),
            samples: tally.samples(),
            limited: self.limited,
            alarm: self.alarm,
            cutting_s: f64::from(self.cutting) * ms_s(period_ms),
            controlled_s: f64::from(self.controlled) * ms_s(period_ms),
            lowest_feed_ipm: self.lowest_ipm,
            holds: self.holds,
        })
    }
}

/// Each tool's part of a firmware run (under QEMU) from its AC periods, as [`HostRun::tools`]
/// has a host run's: `rows` the periods (their tool the firmware's `ac.log` column, the true
/// force and torque of their samples `truth`, `per` to a period), `blocks` each block's time
/// (ns, from..to) and programmed feed (ipm; None: not measured, a rapid), `blocks_done` the
/// blocks the run completed. A part begins at the first period with the next change's tool (the
/// AC follows the tool from the sample after the M6); its blocks are the program's between the
/// changes. Empty for a one-tool cut.
#[allow(clippy::too_many_arguments)]
pub fn tool_runs_of_periods(
    rows: &[AcRow],
    truth: &[(f64, f64)],
    per: usize,
    cut: &Cut,
    blocks: &[(u64, u64, Option<f64>)],
    blocks_done: usize,
    acs: &millac::ac::AcSettings,
    fraction: f64,
) -> Vec<ToolRun> {
    let mut out = Vec::new();
    if cut.changes.is_empty() {
        return out;
    }
    let mut part = ToolPart {
        limited: true,
        ..ToolPart::default()
    };
    let mut plant = cut.tool;
    let mut tally = LoadTally::new(&plant, fraction, acs.sample_hz);
    let mut end_ns = 0;
    for (k, r) in rows.iter().enumerate() {
        let t_ns = r.t_ms * 1_000_000;
        if r.tool != part.tool {
            if let Some((i, c)) = cut
                .changes
                .iter()
                .enumerate()
                .skip(part.part)
                .find(|(_, c)| c.fitted.number == r.tool)
            {
                let next = ToolPart {
                    tool: r.tool,
                    part: i + 1,
                    from_block: c.at_block.min(blocks_done),
                    start_ns: t_ns,
                    limited: c.fitted.limits.is_some(),
                    ..ToolPart::default()
                };
                plant = c.plant;
                let done =
                    std::mem::replace(&mut tally, LoadTally::new(&plant, fraction, acs.sample_hz));
                out.extend(std::mem::replace(&mut part, next).end(
                    t_ns,
                    c.at_block.min(blocks_done),
                    &done,
                    acs.period_ms,
                ));
            }
        }
        for &(f, t) in truth
            .get(k * per..((k + 1) * per).min(truth.len()))
            .unwrap_or(&[])
        {
            tally.add(f, t);
        }
        // The block running at the period's time: its programmed feed (none: no control).
        let i = blocks.partition_point(|b| b.1 < t_ns);
        let programmed = blocks
            .get(i)
            .filter(|b| b.0 <= t_ns)
            .and_then(|b| b.2)
            .unwrap_or(r.feed_ipm);
        part.period(
            (r.f_true_n, r.t_true_nm),
            r.feed_ipm,
            programmed,
            r.state.starts_with("hold"),
            &plant,
        );
        end_ns = t_ns;
    }
    let end = blocks
        .get(blocks_done.saturating_sub(1))
        .map_or(end_ns, |b| b.1.max(end_ns));
    out.extend(part.end(end, blocks_done, &tally, acs.period_ms));
    out
}

/// Milliseconds in seconds.
fn ms_s(ms: u32) -> f64 {
    f64::from(ms) * 1e-3
}

impl ToolRun {
    /// Its time, s.
    pub fn time_s(&self) -> f64 {
        (self.end_ns - self.start_ns) as f64 * 1e-9
    }
}

/// One tool's part of a host run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ToolRun {
    /// Its number (0: before any M6, the cut's tool).
    pub tool: u8,
    /// Its part of the program: 0 before the first change, k after the k-th
    /// ([`Cut::changes`]).
    pub part: usize,
    /// The first block it ran, and the number of blocks.
    pub from_block: usize,
    pub blocks: usize,
    /// Virtual time (ns) when it took over, and when the next one did or the run ended.
    pub start_ns: u64,
    pub end_ns: u64,
    /// Its load figures, against its own limits, and its samples.
    pub load: LoadFigures,
    pub samples: usize,
    /// It had limits (else its AC measured only).
    pub limited: bool,
    /// The alarm that first held the feed while it cut (None: no hold).
    pub alarm: Option<millac::ac::Alarm>,
    /// The AFC log's figures: the time in the cut (AC periods whose highest true force is above
    /// [`CUTTING_SHARE`] of its F_max), the part of it the feed was below the programmed (the
    /// AC controlling, or held), the lowest feed in the cut (None: it never cut), the holds.
    pub cutting_s: f64,
    pub controlled_s: f64,
    pub lowest_feed_ipm: Option<f64>,
    pub holds: u32,
}

/// What a run keeps of itself besides its figures: each of these grows with the program (the
/// path by 40 bytes a pulsed frame, the samples by 24 bytes an ADC sample, the rows by about 200
/// bytes an AC period), so a long program's runs keep only what their caller reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// [`HostRun::path`].
    pub path: bool,
    /// [`HostRun::samples`] and [`HostRun::codes`].
    pub samples: bool,
    /// [`HostRun::rows`].
    pub rows: bool,
    /// F0 as a fraction of the tool's F_max for [`HostRun::load`] (its time above F0).
    pub load_fraction: f64,
}

impl Record {
    /// Everything (the labs, the tests), the load against the paper's F0 = 0.9 F_max.
    pub const ALL: Record = Record {
        path: true,
        samples: true,
        rows: true,
        load_fraction: 0.9,
    };

    /// The figures alone: the time, the load against `load_fraction` x F_max, the block spans,
    /// the stock (memory bounded by the stock grid and the block count).
    pub fn figures(load_fraction: f64) -> Record {
        Record {
            path: false,
            samples: false,
            rows: false,
            load_fraction,
        }
    }
}

/// The host's block queue: as many blocks as the QEMU board's (its 16-slot SPSC queue holds
/// 15), so the loader's record sees the same queue.
pub const HOST_QUEUE: usize = 15;

/// The loader's record of the queued blocks (`millac::rt::replan::Replan`): the queue (16 slots,
/// as the QEMU board's `QUEUE`) and room for nested detours.
pub const REPLAN_RECORD: usize = millac::rt::replan::record_len(HOST_QUEUE + 1);

/// The programmed feed of a block in ipm (0 for rapids and dwells).
pub fn programmed_ipm(settings: &Settings, b: &Block) -> f64 {
    match b.motion {
        Motion::Linear(l) => feed_ipm(settings, l.f),
        Motion::Arc(c) => feed_ipm(settings, c.f),
        _ => 0.0,
    }
}

/// The simulated process as the firmware's ADC port (host): converts at the sample's time with
/// the encoder counts, applies the injected faults (the same [`crate::host::fault::Injector`] the QEMU
/// co-simulation's `Faulty` plant applies), and keeps the true force and torque of every sample.
/// A fault that delivers no conversion (dropout) is a missed conversion, as under QEMU.
struct HostAdc {
    process: Process,
    injector: crate::host::fault::Injector,
    sample_hz: u32,
    /// True force and torque of the samples: every one with [`Record::samples`], else the last
    /// AC period's (what its row reports).
    truth: Vec<(f64, f64)>,
    /// The codes the controller got at every sample (None: a missed conversion), with
    /// [`Record::samples`].
    codes: Vec<Option<[u16; 3]>>,
    keep: bool,
    /// The run's load figures, each sample against the limits of the tool that cut it.
    tally: LoadTally,
    /// The same for the tool in the spindle alone ([`ToolRun::load`]).
    part: LoadTally,
}

impl HostAdc {
    /// Virtual time of sample `index` (the sample clock's (index + 1)-th tick).
    fn time_s(&self, index: u32) -> f64 {
        (u64::from(index) + 1) as f64 / f64::from(self.sample_hz)
    }
}

/// What one sample gave the controller: the codes (None for a missed conversion), the AC period
/// due, if any, and the sound channel's codes (None: no microphone).
type HostSampled = (
    Option<[u16; 3]>,
    Option<u32>,
    Option<[u16; millac::wire::SOUND_PER_SAMPLE]>,
);

/// The sampler body of the firmware (`millac::rt::ac::sample`, with its overload trip when the
/// AC is applied) over the host ADC.
fn sample(
    adc: &mut HostAdc,
    status: &SamplerWriter,
    per_period: u32,
    trip: Option<&rt_ac::Trip>,
) -> HostSampled {
    match rt_ac::sample(adc, status, per_period, trip) {
        rt_ac::Sampled::Codes { codes, due, sound } => (codes, due, sound),
        // Not reached: the host ADC never goes away.
        rt_ac::Sampled::Lost { due } => (None, due, None),
    }
}

impl ForceTorqueAdc for HostAdc {
    fn sample(&mut self, index: u32, encoder: [i32; 3]) -> Conversion {
        let t_s = self.time_s(index);
        let s = self.process.sample(t_s, encoder.map(i64::from));
        self.truth.push((s.f_true_n, s.t_true_nm));
        self.tally.add(s.f_true_n, s.t_true_nm);
        self.part.add(s.f_true_n, s.t_true_nm);
        let codes = self.injector.apply(t_s, s.codes);
        if self.keep {
            self.codes.push(codes);
        }
        match codes {
            Some(codes) => Conversion::Fresh(codes),
            None => Conversion::Missed,
        }
    }

    /// The flexible tool's microphone, the same block per sample the QEMU board's ADC delivers.
    fn sound(&mut self) -> Option<[u16; millac::wire::SOUND_PER_SAMPLE]> {
        self.process.take_sound_block()
    }
}

/// Frame period in ns for a rate: the reload the firmware computes for the QEMU board
/// (`millac::rt::Reloads::for_settings`, the same clock), in whole timer clocks.
pub fn period_ns(settings: &Settings, rate: Rate) -> u64 {
    let reloads = millac::rt::Reloads::for_settings::<crate::lm3s_facts::Lm3s6965>(settings);
    crate::host::board::reload_ns(reloads.of(rate))
}

/// The time the frame takes over `prog` at the programmed feeds, s: its own frames, each at the
/// rate it ran at (`check`'s estimate; a run under QEMU shows its virtual time against it).
pub fn estimated_time_s(prog: &[ProgBlock], settings: &Settings) -> f64 {
    let mut frame = millac::nc::Frame::new(FrameConfig::from_settings(settings));
    let blocks = prog.iter().map(|b| b.block);
    let ns: u64 = millac::nc::sim::Sim::new(&mut frame, blocks, u32::MAX, u64::MAX)
        .map(|f| period_ns(settings, f.rate))
        .sum();
    ns as f64 * 1e-9
}

/// Path speed (ipm, or the program's unit per minute) of a position change `d` over one period:
/// the `feed_ipm` of ac.csv, for host runs and QEMU logs alike.
pub fn path_feed_ipm(settings: &Settings, d: [i64; 3], period_ms: u32) -> f64 {
    let (num, den) = settings.blu.per_inch();
    let len = d.iter().map(|v| (*v as f64).powi(2)).sum::<f64>().sqrt();
    len / (num as f64 / den as f64) / (period_ms as f64 / 60_000.0)
}

/// Feed number -> ipm (or the program's unit per minute).
pub fn feed_ipm(settings: &Settings, f: u32) -> f64 {
    let (num, den) = settings.blu.per_inch();
    f as f64 * settings.frame_hz as f64 * 60.0 / (num as f64 / den as f64) / settings.q0 as f64
}

/// Runs `prog` with the process; `ac` None = no adaptive control (programmed feeds). The
/// controller gets the achieved feed every period (anti-windup), as in the firmware.
pub fn run(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
) -> Result<HostRun> {
    run_with(prog, settings, cut, ac, true)
}

/// The pulses of `prog` at its programmed feeds without the process: the frames alone, the same
/// `path`, `spans`, machining time and final position as [`run`] with `ac` None (no sample, no
/// row, no stock cut). What the oracle walks and the optimiser plans on, for a fraction of the
/// process' time.
pub fn pulses(prog: &[ProgBlock], settings: &Settings, cut: &Cut) -> Result<HostRun> {
    let record = Record {
        path: true,
        ..Record::figures(Record::ALL.load_fraction)
    };
    let taps = Taps::default();
    run_inner(prog, settings, cut, None, true, &[], false, record, taps)
}

/// As [`pulses`], each pulse given to `on_pulse` (position and block index) as the frame puts it
/// out instead of kept in the path.
pub fn pulses_to(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    on_pulse: &mut dyn FnMut([i64; 3], usize),
) -> Result<HostRun> {
    let record = Record::figures(Record::ALL.load_fraction);
    let taps = Taps {
        pulse: Some(on_pulse),
        row: None,
    };
    run_inner(prog, settings, cut, None, true, &[], false, record, taps)
}

/// As [`run_with_faults`] with anti-windup, keeping what `record` says; `on_row` (if any) gets
/// each AC period's row as it is made (kept in the run only with [`Record::rows`]): `host` writes
/// ac.csv as the run goes.
pub fn run_recorded(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
    faults: &[crate::host::fault::Fault],
    record: Record,
    on_row: Option<&mut dyn FnMut(&AcRow)>,
) -> Result<HostRun> {
    let taps = Taps {
        pulse: None,
        row: on_row,
    };
    run_inner(prog, settings, cut, ac, true, faults, true, record, taps)
}

/// What a run hands its caller as it goes: every pulsed frame's position and block index, every
/// AC period's row.
#[derive(Default)]
struct Taps<'a> {
    pulse: Option<&'a mut dyn FnMut([i64; 3], usize)>,
    row: Option<&'a mut dyn FnMut(&AcRow)>,
}

/// As [`run`]; `anti_windup` false runs the paper's FRC exactly (no achieved feed).
pub fn run_with(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
    anti_windup: bool,
) -> Result<HostRun> {
    run_with_faults(prog, settings, cut, ac, anti_windup, &[])
}

/// As [`run_with`], with sensor faults injected into the codes the controller samples (see
/// [`crate::host::fault`]; the zero-force codes are the AC calibration's offsets). The true force and
/// torque of `HostRun::samples` are the process's. The process monitors run as the AC settings
/// say (`$266` chatter threshold, `$268` breakage, `$267` flutes;
/// `millac::rt::ac::AcPeriod::with_monitors` and `millac::rt::monitor::ChatterTask`, the
/// firmware's code) at the cut's spindle speed (the program's S, as the firmware's tape tells the
/// monitors); they need the AC (`ac`).
pub fn run_with_faults(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
    anti_windup: bool,
    faults: &[crate::host::fault::Fault],
) -> Result<HostRun> {
    run_inner(
        prog,
        settings,
        cut,
        ac,
        anti_windup,
        faults,
        true,
        Record::ALL,
        Taps::default(),
    )
}

/// [`run_with_faults`]; `plant` false: no sample is taken ([`pulses`], without AC); `record`:
/// what the run keeps; `taps` get every pulse and row as they come.
#[allow(clippy::too_many_arguments)] // the public entry points' inputs, one body
fn run_inner(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
    anti_windup: bool,
    faults: &[crate::host::fault::Fault],
    plant: bool,
    record: Record,
    mut taps: Taps,
) -> Result<HostRun> {
    // The firmware's frame ISR and pulse end on the host board, and its status words (the
    // contexts' handles: the frame's and the pulse end's in the host board, the others below).
    let status = Status::new();
    let w = status.split();
    let mut frames = HostFrames::new(settings, w.frame, w.pulse);
    // An enabled AC's feed ceiling, as the firmware's tape applies it (the same function).
    let cfg = FrameConfig::from_settings(settings);
    let ceiling = ac.map(|s| s.ceiling);
    // The program, fed to the queue through the loader's record as the firmware's loader feeds
    // it (chatter suppression re-plans from that record).
    let mut program: VecDeque<Sealed> = prog
        .iter()
        .map(|b| finish_block(b.block.into_block(), ceiling, &cfg, settings.q0))
        .collect();
    let mut queue = HostQueue {
        blocks: VecDeque::new(),
        cap: HOST_QUEUE,
    };
    let acs = ac.unwrap_or_default();
    // Chatter reactions need the monitors, which need the AC.
    let reactions = match ac {
        Some(s) => s,
        None => AcSettings {
            chatter_step_mm: 0.0,
            chatter_max_rpm: 0,
            ..acs
        },
    };
    let mut replan = Replan::<REPLAN_RECORD>::new(*settings, &reactions, [0; 3]);
    // The firmware's sampler and AC period (`millac::rt::ac`) over the host status and ADC.
    w.loader.set_spindle_rpm(cut.spindle_rpm.round() as u32);
    // The AC settings checked once: the controller and the monitors take them as they are.
    let ac = ac
        .map(AcSettings::validated)
        .transpose()
        .map_err(|e| anyhow!("AC settings: {}", e.message()))?;
    let mut period = match ac {
        Some(s) => {
            let p = AcPeriod::new(AcController::new(s), *settings, true, &w.ac).with_monitors(&s);
            Some(if anti_windup {
                p
            } else {
                p.without_anti_windup()
            })
        }
        None => None,
    };
    // The sampler's overload trip for the tool in the spindle (the AC is applied here whenever
    // it runs).
    let mut trip = ac.map(rt_ac::ToolTrip::new);
    let mut chatter = ac
        .as_ref()
        .and_then(millac::rt::monitor::ChatterTask::from_settings);
    let mut verdict = None;
    let mut adc = HostAdc {
        process: cut.process()?,
        injector: crate::host::fault::Injector::new(faults, acs.cal.map(|c| f64::from(c.offset))),
        sample_hz: acs.sample_hz,
        truth: Vec::new(),
        codes: Vec::new(),
        keep: record.samples,
        tally: LoadTally::new(&cut.tool, record.load_fraction, acs.sample_hz),
        part: LoadTally::new(&cut.tool, record.load_fraction, acs.sample_hz),
    };
    let per_period = acs.samples_per_period();
    let sample_ns = 1_000_000_000 / acs.sample_hz as u64;
    let mut out = HostRun::default();
    let (mut t, mut next_sample) = (0u64, sample_ns);
    // The operator's word as the loader keeps it (the host has no operator: run, 100 %).
    let word = status.operator.get();
    // The controller's feed number, as the firmware logs it (under the plan k x f_max).
    let mut logged_cap = u32::MAX;
    let mut pos = [0i64; 3];
    let mut period_start = pos;
    let (mut first, mut last) = (None, 0u64);
    let mut block_feed = 0.0;
    // The programmed feed and the block index of the pulses the last interrupt computed (they go
    // out at the next one).
    let mut computed = (0.0, 0usize);
    let mut ticks = 0u32;
    // The program's tool changes still to make, the blocks offered so far, the tool cutting
    // (its part of the run: the tally against its limits, its first block and time).
    let mut changes = cut.changes.iter().peekable();
    let mut offered = 0usize;
    let mut part = ToolPart {
        limited: true,
        ..ToolPart::default()
    };
    loop {
        ticks = ticks.wrapping_add(1);
        if ticks % 4096 == 0 {
            crate::progress::update(frames.frame().blocks_done() as usize, t as f64 * 1e-9);
        }
        // An M6: once the blocks before it have run and the machine stands (a sync line of the
        // firmware's loader), the tool is fitted, told as the loader tells it, and cut with.
        if let Some(c) = changes.peek().filter(|c| {
            c.at_block == offered
                && queue.blocks.is_empty()
                && status.idle.get()
                && !replan.pending()
                && !replan.aborting()
        }) {
            w.loader.set_tool(&c.fitted);
            w.loader.ask_new_job();
            w.loader.set_spindle_rpm(c.rpm.round() as u32);
            if plant && part.tool != 0 {
                out.stocks.push((part.tool, adc.process.stock().clone()));
            }
            if plant {
                adc.process
                    .change_tool(c.plant, c.rpm)
                    .map_err(|e| anyhow!("T{} at line {}: {}", c.fitted.number, c.line, e.0))?;
                adc.tally.retool(&c.plant);
            }
            let blocks = frames.frame().blocks_done() as usize;
            let next = ToolPart {
                tool: c.fitted.number,
                part: part.part + 1,
                from_block: blocks,
                start_ns: t,
                limited: c.fitted.limits.is_some(),
                ..ToolPart::default()
            };
            let tally = LoadTally::new(&c.plant, record.load_fraction, acs.sample_hz);
            let done = std::mem::replace(&mut adc.part, tally);
            out.tools.extend(std::mem::replace(&mut part, next).end(
                t,
                blocks,
                &done,
                acs.period_ms,
            ));
            changes.next();
        }
        while changes.peek().is_none_or(|c| offered < c.at_block) {
            let Some(b) = program.pop_front() else { break };
            if let Err(b) = replan.offer(&mut queue, b) {
                program.push_front(b);
                break;
            }
            offered += 1;
        }
        let frame = frames.frame();
        if frame.idle() {
            match queue.blocks.front() {
                // The end of the job as the loader sees it: the frame published idle (its last
                // pulses out) and nothing left to load.
                None if status.idle.get()
                    && program.is_empty()
                    && !replan.pending()
                    && !replan.aborting() =>
                {
                    break
                }
                None => {}
                Some(b) => block_feed = programmed_ipm(settings, b),
            }
        }
        let was_idle = frame.idle();
        let done_before = frame.blocks_done();
        // The loader's word, held while the AC holds (as the firmware's loaders publish it); not
        // while the frame drops the queue for a re-plan: that word carries the abort bit until
        // `Replan::poll` has finished it.
        if !replan.aborting() {
            w.loader.set_operator(millac::nc::operator::with_ac_hold(
                word,
                status.feed_cap.get(),
            ));
        }
        // The frame interrupt at t: the pulses the interrupt before computed go out now.
        let irq = frames.interrupt(&mut queue);
        if irq.pulsed {
            pos = status.encoder().map(i64::from);
            first.get_or_insert(t);
            last = t;
            if record.path {
                out.path.push((pos, computed.0, computed.1));
            }
            if let Some(f) = taps.pulse.as_mut() {
                f(pos, computed.1);
            }
        }
        let t0 = t;
        t += irq.period_ns;
        let frame = frames.frame();
        if was_idle && !frame.idle() {
            // A block loaded from idle: its span starts with this frame.
            out.spans.push((out.spans.len(), t0, t));
        } else if let Some(span) = out.spans.last_mut() {
            if !was_idle {
                span.2 = t;
            }
        }
        computed = (block_feed, out.spans.len().saturating_sub(1));
        // A line chained at the end of the line before (no idle frame between them): this frame's
        // pulses are the old block's last ones; the new block's span starts after it.
        let chained = !was_idle && !frame.idle() && frame.blocks_done() != done_before;
        if chained {
            out.spans.push((out.spans.len(), t, t));
            block_feed = queue
                .blocks
                .front()
                .map_or(0.0, |b| programmed_ipm(settings, b));
        }
        let mut halt = false;
        // The samples up to the next frame interrupt (one at the same instant runs after it).
        while plant && next_sample < t {
            next_sample += sample_ns;
            let trip = trip.as_mut().and_then(|t| t.follow(&status));
            let (codes, due, sound) = sample(&mut adc, &w.sampler, per_period, trip);
            if let (Some(ac), Some(codes)) = (period.as_mut(), codes) {
                ac.sample(codes, &w.ac);
            }
            // The sampler's trip writes the frame's cap between periods (the frame reads it every
            // frame).
            if status.feed_cap.get() == 0 && out.hold_ns.is_none() {
                out.hold_ns = Some(next_sample - sample_ns);
            }
            // The chatter monitor's task (its own in the firmware, below the AC task): each
            // record's spectrum. The firmware's monitor runs after the AC period of the tick that
            // spawns them both, so a verdict reaches the AC period one period after the first
            // period that follows the record: kept here until that period has run.
            if let (Some(m), Some(sound)) = (chatter.as_mut(), sound) {
                if let Some(spec) = m.sound(&sound, &status) {
                    out.spectra.push((next_sample as f64 * 1e-9, spec));
                    verdict = verdict.or(Some(spec));
                }
            }
            let Some(due) = due else { continue };
            let heard = verdict.take();
            let d = [0, 1, 2].map(|k| pos[k] - period_start[k]);
            let mut estimates = None;
            let (f_meas, t_meas, e, state) = match period.as_mut() {
                Some(ac) => {
                    let r = ac.run(&w.ac);
                    if let Some(v) = heard {
                        ac.heard(v);
                    }
                    estimates = ac.ctl.law_estimates();
                    halt = r.halt;
                    let o = r.out;
                    if status.feed_cap.get() == 0 && out.hold_ns.is_none() {
                        out.hold_ns = Some(next_sample - sample_ns);
                    }
                    logged_cap = o.feed_cap;
                    if out.alarm.is_none() {
                        out.alarm = o.alarm;
                    }
                    if part.alarm.is_none() {
                        part.alarm = o.alarm;
                    }
                    let state = match o.state {
                        AcState::Run => "run".to_string(),
                        AcState::Hold(a) => {
                            out.held = true;
                            format!("hold:{}", a.message())
                        }
                    };
                    (o.f_n as f64, o.t_nm as f64, o.e as f64, state)
                }
                None => (0.0, 0.0, 0.0, "off".to_string()),
            };
            let window = adc
                .truth
                .get(adc.truth.len().saturating_sub(per_period as usize)..)
                .unwrap_or(&[]);
            let f_true = window.iter().map(|s| s.0).fold(0.0, f64::max);
            let t_true = window.iter().map(|s| s.1).fold(0.0, f64::max);
            let feed = path_feed_ipm(settings, d, acs.period_ms);
            if plant {
                let held = state.starts_with("hold");
                part.period((f_true, t_true), feed, block_feed, held, adc.process.tool());
            }
            let row = (record.rows || taps.row.is_some()).then(|| AcRow {
                t_ms: u64::from(due) * 1000 / u64::from(acs.sample_hz),
                pos_blu: pos,
                feed_ipm: feed,
                f_meas_n: f_meas,
                t_meas_nm: t_meas,
                f_true_n: f_true,
                t_true_nm: window.iter().map(|s| s.1.abs()).fold(0.0, f64::max),
                e,
                state,
                feed_cap: logged_cap,
                estimates,
                tool: part.tool,
            });
            if let (Some(f), Some(r)) = (taps.row.as_mut(), &row) {
                f(r);
            }
            out.rows.extend(row.filter(|_| record.rows));
            // Without the samples kept: the last period's are all a row reads.
            if !adc.keep && adc.truth.len() > 2 * per_period as usize {
                let drop = adc.truth.len() - per_period as usize;
                adc.truth.drain(..drop);
            }
            period_start = pos;
        }
        // The loader's turn: chatter suppression.
        match replan.poll(&mut queue, &w.loader) {
            ReplanEvent::None => {}
            ReplanEvent::Replanned(r) => out.replans.push((t as f64 * 1e-9, r)),
            ReplanEvent::Refused { why, .. } => out.refused.push((t as f64 * 1e-9, why)),
            ReplanEvent::Speed(s) => {
                // The simulated spindle, as the firmware's board turns its spindle.
                adc.process
                    .set_spindle_rpm(f64::from(s.to))
                    .map_err(|e| anyhow!("chatter spindle speed S{}: {}", s.to, e.0))?;
                replan.speed_applied(&w.loader, s.to);
                out.speeds.push((t as f64 * 1e-9, s));
            }
        }
        if halt {
            break;
        }
        if crate::interrupt::received().is_some() {
            out.interrupted = true;
            break;
        }
    }
    let blocks = frames.frame().blocks_done() as usize;
    if plant && !cut.changes.is_empty() {
        out.stocks.push((part.tool, adc.process.stock().clone()));
    }
    if !cut.changes.is_empty() {
        out.tools
            .extend(part.end(t, blocks, &adc.part, acs.period_ms));
    }
    out.stock = plant.then(|| adc.process.into_stock());
    out.load = adc.tally.figures();
    out.sample_count = adc.tally.samples();
    if adc.keep {
        out.samples = adc.truth;
    }
    out.codes = adc.codes;
    out.machining_time_s = first.map_or(0.0, |f| (last - f) as f64 * 1e-9);
    out.last_pulse_ns = last;
    out.final_position = pos;
    out.blocks_done = frames.frame().blocks_done() as usize;
    Ok(out)
}

/// The ac.csv header; column names are stable.
pub const CSV_HEADER: &str =
    "t_ms,x_blu,y_blu,z_blu,feed_ipm,f_meas_n,t_meas_nm,f_true_n,t_true_nm,e,state,tool\n";

/// One row of ac.csv (with its newline).
pub fn csv_line(r: &AcRow) -> String {
    format!(
        "{},{},{},{},{:.3},{:.1},{:.3},{:.1},{:.3},{:.4},{},{}\n",
        r.t_ms,
        r.pos_blu[0],
        r.pos_blu[1],
        r.pos_blu[2],
        r.feed_ipm,
        r.f_meas_n,
        r.t_meas_nm,
        r.f_true_n,
        r.t_true_nm,
        r.e,
        r.state,
        r.tool
    )
}

/// The ac.csv text (header + one row per AC period).
pub fn csv(rows: &[AcRow]) -> String {
    let mut s = String::from(CSV_HEADER);
    for r in rows {
        s += &csv_line(r);
    }
    s
}

/// The rows of a run for its plot, at most `2 x max` of them whatever its length: every row
/// until there are `2 x max`, then one row for each `stride` rows of the run (doubled as
/// needed), the one with the highest true force among them (the plot shows the load against
/// the limits).
#[derive(Clone, Debug)]
pub struct PlotRows {
    pub rows: Vec<AcRow>,
    /// Rows of the run per row kept.
    pub stride: usize,
    max: usize,
    bucket: Option<AcRow>,
    in_bucket: usize,
}

impl PlotRows {
    pub fn new(max: usize) -> PlotRows {
        PlotRows {
            rows: Vec::new(),
            stride: 1,
            max: max.max(1),
            bucket: None,
            in_bucket: 0,
        }
    }

    fn louder(a: AcRow, b: AcRow) -> AcRow {
        if b.f_true_n > a.f_true_n {
            b
        } else {
            a
        }
    }

    pub fn push(&mut self, r: &AcRow) {
        let r = r.clone();
        self.bucket = Some(match self.bucket.take() {
            Some(b) => Self::louder(b, r),
            None => r,
        });
        self.in_bucket += 1;
        if self.in_bucket < self.stride {
            return;
        }
        self.in_bucket = 0;
        self.rows.extend(self.bucket.take());
        if self.rows.len() >= 2 * self.max {
            let rows = std::mem::take(&mut self.rows);
            let mut it = rows.into_iter();
            while let Some(a) = it.next() {
                self.rows.push(match it.next() {
                    Some(b) => Self::louder(a, b),
                    None => a,
                });
            }
            self.stride *= 2;
        }
    }

    /// The rows kept (the last, partial stride's included).
    pub fn finish(mut self) -> PlotRows {
        self.rows.extend(self.bucket.take());
        self
    }
}

/// Force/torque figures of a run against the tool's limits (F0, T0 = fraction x limits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadFigures {
    pub peak_force_ratio: f64,
    pub peak_torque_ratio: f64,
    pub time_above_f0_s: f64,
    pub time_above_limit_s: f64,
}

pub fn load_figures(
    samples: &[(f64, f64)],
    tool: &Tool,
    fraction: f64,
    sample_hz: u32,
) -> LoadFigures {
    let mut tally = LoadTally::new(tool, fraction, sample_hz);
    for &(f, t) in samples {
        tally.add(f, t);
    }
    tally.figures()
}

/// [`load_figures`] of a multi-tool run whose samples are grouped `per` to an AC period and
/// whose periods were cut by `period_tools` (a QEMU run's `ac.log` tool column): each sample
/// against the limits of the tool that cut it (the cut's tool until the first change, then each
/// of `cut.changes` as its tool comes, in order).
pub fn load_figures_by_tool(
    samples: &[(f64, f64)],
    period_tools: &[u8],
    per: usize,
    cut: &Cut,
    fraction: f64,
    sample_hz: u32,
) -> LoadFigures {
    let mut tally = LoadTally::new(&cut.tool, fraction, sample_hz);
    let mut changes = cut.changes.iter();
    let mut tool = 0;
    for (k, &(f, t)) in samples.iter().enumerate() {
        let now = period_tools.get(k / per.max(1)).copied().unwrap_or(tool);
        if now != tool {
            tool = now;
            if let Some(c) = changes.by_ref().find(|c| c.fitted.number == now) {
                tally.retool(&c.plant);
            }
        }
        tally.add(f, t);
    }
    tally.figures()
}

/// [`LoadFigures`] one sample at a time (a run's, without keeping its samples).
#[derive(Clone, Copy, Debug)]
pub struct LoadTally {
    f_max: f64,
    t_max: f64,
    f0: f64,
    fraction: f64,
    dt: f64,
    /// The highest force and torque over the limits of the tool that met them.
    peak_f: f64,
    peak_t: f64,
    above_f0: u64,
    above_limit: u64,
    samples: usize,
}

impl LoadTally {
    /// Against `tool`'s limits, F0 = `fraction` x F_max, samples at `sample_hz`.
    pub fn new(tool: &Tool, fraction: f64, sample_hz: u32) -> LoadTally {
        LoadTally {
            f_max: tool.f_max_n,
            t_max: tool.t_max_nm,
            f0: fraction * tool.f_max_n,
            fraction,
            dt: 1.0 / sample_hz as f64,
            peak_f: 0.0,
            peak_t: 0.0,
            above_f0: 0,
            above_limit: 0,
            samples: 0,
        }
    }

    /// One sample's true force (N) and torque (N*m).
    pub fn add(&mut self, f: f64, t: f64) {
        // Over the limits sample by sample (division is monotone: the same as the peak over the
        // limit while the tool stays).
        self.peak_f = self.peak_f.max(f / self.f_max);
        self.peak_t = self.peak_t.max(t.abs() / self.t_max);
        self.above_f0 += u64::from(f > self.f0);
        self.above_limit += u64::from(f > self.f_max || t.abs() > self.t_max);
        self.samples += 1;
    }

    /// The samples added.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// The samples from now on are `tool`'s, against its limits (a tool change).
    pub fn retool(&mut self, tool: &Tool) {
        self.f_max = tool.f_max_n;
        self.t_max = tool.t_max_nm;
        self.f0 = self.fraction * tool.f_max_n;
    }

    pub fn figures(&self) -> LoadFigures {
        LoadFigures {
            peak_force_ratio: self.peak_f,
            peak_torque_ratio: self.peak_t,
            time_above_f0_s: self.above_f0 as f64 * self.dt,
            time_above_limit_s: self.above_limit as f64 * self.dt,
        }
    }
}

/// The fastest feed change of a sealed feed block, ipm/s: its acceleration ramp (Q8 feed numbers
/// per frame) at the frame rate; 0 for rapids and dwells.
pub fn ramp_ipm_s(settings: &Settings, b: &Block) -> f64 {
    let ramp = match b.motion {
        Motion::Linear(l) => l.ramp,
        Motion::Arc(c) => c.ramp,
        _ => return 0.0,
    };
    f64::from(ramp) / 256.0 * f64::from(settings.frame_hz) * feed_ipm(settings, 1)
}

/// The same program with every feed block at one constant feed number `f`, or at its own feed
/// where that is lower (a feed block's feed is its ceiling: pass the blocks the AC runs,
/// [`crate::evaluation::acreport::ceiling_blocks`], to honour the AC's ceiling setting).
pub fn with_constant_feed(prog: &[ProgBlock], f: u32, settings: &Settings) -> Vec<ProgBlock> {
    with_constant_feeds(prog, |_| f, settings)
}

/// As [`with_constant_feed`], block `i` at its own feed number `f(i)` (or its own feed when
/// lower): each tool's part of a program at its own constant feed.
pub fn with_constant_feeds(
    prog: &[ProgBlock],
    f: impl Fn(usize) -> u32,
    settings: &Settings,
) -> Vec<ProgBlock> {
    let cfg = FrameConfig::from_settings(settings);
    prog.iter()
        .enumerate()
        .map(|(i, b)| {
            let f = f(i);
            let mut block = b.block.into_block();
            match &mut block.motion {
                Motion::Linear(l) => l.f = l.f.min(f),
                Motion::Arc(c) => c.f = c.f.min(f),
                _ => {}
            }
            ProgBlock {
                block: block.seal(&cfg),
                ..*b
            }
        })
        .collect()
}
