//! Runs a program through the firmware under QEMU and analyses the capture (host): the machinery
//! behind `millac run` and the QEMU tests.
use crate::analysis::{self, ProgBlock, Report};
use crate::emulator::capture::{run_capture, Capture, CaptureSpec, HandlerSpec};
use crate::{analysis::vcd, emulator::cosim, emulator::firmware};
use anyhow::{Context, Result};
use millac::Settings;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Duration;

/// The default QEMU `-icount` shift of the host tool: one instruction = 16 ns (62.5 MIPS, close
/// to a 50-72 MHz Cortex-M3).
pub const DEFAULT_SHIFT: u32 = 4;
/// The largest `-icount` shift QEMU accepts (7.2: "Invalid shift value" above it).
pub const QEMU_MAX_SHIFT: u32 = 10;
/// The largest shift at which the firmware keeps its frame: the rapid frame period at the
/// default settings is 38 us (26 333 Hz); the frame ISR's worst case (about 185 instructions) and
/// the pulse end (about 45) take 29 us at shift 7 (128 ns per instruction) and 59 us at shift 8,
/// where the frames overrun in rapids: the firmware holds with its frame overrun alarm
/// (`ALARM:111`; before it had that check it lost step pulses: 9378 of 15748 X pulses of
/// `G21 G0 X10 Y-7 Z3` and back). Measured:
/// `firmware::the_largest_shift_allowed_keeps_every_pulse_and_the_next_does_not`. The host tool
/// refuses larger shifts ([`check_shift`]).
pub const MAX_SHIFT: u32 = 7;

/// `--shift N`: the QEMU time scale the firmware can keep, or why not (a message for the
/// command line).
pub fn check_shift(shift: u32) -> Result<u32, String> {
    if shift > QEMU_MAX_SHIFT {
        return Err(format!(
            "{shift} is not a QEMU -icount shift (0..={QEMU_MAX_SHIFT}); the firmware keeps its \
             frame up to {MAX_SHIFT}: use 0..={MAX_SHIFT} (default {DEFAULT_SHIFT})"
        ));
    }
    if shift > MAX_SHIFT {
        let ns = 1u64 << shift;
        return Err(format!(
            "at shift {shift} one instruction takes {ns} ns: the frame interrupt's worst case \
             (about 230 instructions with the pulse end, {} us) no longer fits the 38 us rapid \
             frame period, so the firmware cannot keep its frame in rapids (it holds with a frame \
             overrun; measured: shift 8 overruns, 7 keeps every pulse); use 0..={MAX_SHIFT} \
             (default {DEFAULT_SHIFT})",
            230 * ns / 1000
        ));
    }
    Ok(shift)
}

/// What a run produced.
pub struct Outcome {
    /// summary.json as written.
    pub summary: Value,
    /// None when the program was rejected before running.
    pub report: Option<Report>,
    pub capture: Option<Capture>,
    /// All checks passed (program accepted, end points exact, pulses equal the host core's,
    /// firmware and capture agree on the final position).
    pub ok: bool,
    /// With the simulated ADC: every sample exchanged and the firmware's AC log.
    pub exchanges: Vec<cosim::Exchange>,
    pub ac_log: Vec<cosim::AcRecord>,
}

/// Runs the firmware on `text` as program.nc in `out` with no pre-check, and returns the capture
/// (handlers: TIMER_0A frame, TIMER_1A pulse end). The firmware's exit status is in the capture.
/// The simulated ADC is absent (stale FIFOs of an earlier co-simulation in `out` are removed).
pub fn execute(text: &str, out: &Path, shift: u32) -> Result<Capture> {
    execute_until(text, out, shift, None)
}

/// [`execute`], QEMU stopped early (SIGTERM, the capture is what ran) once `stop` is set.
fn execute_until(text: &str, out: &Path, shift: u32, stop: Option<Stop>) -> Result<Capture> {
    let mut spec = prepare(text, out, shift)?;
    spec.stop = stop;
    for f in [cosim::REQ, cosim::RESP] {
        let p = out.join(f);
        if std::fs::symlink_metadata(&p).is_ok() {
            std::fs::remove_file(&p).with_context(|| format!("removing {}", p.display()))?;
        }
    }
    run_capture(&spec)
}

/// Builds the firmware, writes program.nc and returns the capture spec (handlers: TIMER_0A frame,
/// TIMER_1A pulse end, TIMER_2A sampler, SSI0 the AC period's dispatcher, I2C0 the chatter
/// monitor's).
fn prepare(text: &str, out: &Path, shift: u32) -> Result<CaptureSpec> {
    // The firmware would run the program on a stored record (see `serve`), while the checks here
    // assume the defaults: refuse rather than report false mismatches, and delete nothing.
    let stored = out.join(crate::lm3s_files::SETTINGS_NAME);
    if std::fs::symlink_metadata(&stored).is_ok() {
        anyhow::bail!(
            "{} holds serve's settings; runs check against the default settings: use another --out",
            stored.display()
        );
    }
    let elf = firmware::build()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let program = out.join("program.nc");
    std::fs::write(&program, text).with_context(|| format!("writing {}", program.display()))?;
    let mut spec = CaptureSpec::new(&elf, out);
    spec.icount_shift = shift;
    spec.timeout = Duration::from_secs(1800);
    spec.handlers = vec![
        HandlerSpec::from_elf(&elf, "TIMER_0A")?,
        HandlerSpec::from_elf(&elf, "TIMER_1A")?,
        HandlerSpec::from_elf(&elf, "TIMER_2A")?,
        HandlerSpec::from_elf(&elf, "SSI0")?,
        HandlerSpec::from_elf(&elf, "I2C0")?,
    ];
    Ok(spec)
}

/// The settings record of a run whose AC settings are not the defaults (another `--strategy`):
/// `out/settings.bin` ([`crate::lm3s_files::SETTINGS_NAME`], the file the firmware loads at start-up),
/// written before QEMU starts and removed when the run ends (dropped), so the next run in `out`
/// passes [`prepare`]'s check and a default run writes no file (its runs stay byte-identical).
/// The NC settings stay the defaults the checks assume.
struct RunSettings(Option<std::path::PathBuf>);

impl RunSettings {
    fn write(
        out: &Path,
        acs: &millac::ac::AcSettings,
        tools: &millac::gcode::tools::ToolTable,
    ) -> Result<RunSettings> {
        if *acs == millac::ac::AcSettings::default() && *tools == Default::default() {
            return Ok(RunSettings(None));
        }
        acs.validate()
            .map_err(|e| anyhow::anyhow!("AC settings: {}", e.message()))?;
        let record = millac::protocol::table::record::encode(&run_record(acs, tools));
        let path = out.join(crate::lm3s_files::SETTINGS_NAME);
        std::fs::write(&path, record).with_context(|| format!("writing {}", path.display()))?;
        Ok(RunSettings(Some(path)))
    }
}

impl Drop for RunSettings {
    fn drop(&mut self) {
        if let Some(p) = &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// The settings a run gives the firmware: the defaults with the run's AC settings and the
/// machine's tool table.
pub fn run_record(
    acs: &millac::ac::AcSettings,
    tools: &millac::gcode::tools::ToolTable,
) -> millac::protocol::table::MachineSettings {
    let d = millac::protocol::table::MachineSettings::default();
    millac::protocol::table::MachineSettings {
        ac: *acs,
        work: millac::gcode::Work {
            tools: *tools,
            ..d.work
        },
        ..d
    }
}

/// Runs the firmware on `text` like [`execute`], with the lockstep simulated ADC served by
/// `plant` (see [`cosim`]): `ac_enabled` = the firmware applies the controller's feed cap (else it
/// only measures and logs). Returns the capture and every ADC exchange; the firmware's AC log is
/// `out/ac.log` (parse it with [`cosim::parse_ac_log`]). The default AC settings.
pub fn execute_with_plant(
    text: &str,
    out: &Path,
    shift: u32,
    plant: Box<dyn cosim::Plant + Send>,
    ac_enabled: bool,
) -> Result<(Capture, Vec<cosim::Exchange>)> {
    let acs = millac::ac::AcSettings::default();
    execute_with_plant_settings(text, out, shift, plant, ac_enabled, &acs)
}

/// As [`execute_with_plant`], the firmware running on the AC settings `acs` (e.g. another
/// strategy): a settings record in `out` for the run when they are not the defaults.
pub fn execute_with_plant_settings(
    text: &str,
    out: &Path,
    shift: u32,
    plant: Box<dyn cosim::Plant + Send>,
    ac_enabled: bool,
    acs: &millac::ac::AcSettings,
) -> Result<(Capture, Vec<cosim::Exchange>)> {
    let tools = Default::default();
    execute_with_plant_until(text, out, shift, plant, ac_enabled, acs, &tools, None)
}

/// [`execute_with_plant_settings`] on a machine with the tool table `tools`, QEMU stopped early
/// once `stop` is set.
#[allow(clippy::too_many_arguments)] // the run's inputs, one body
fn execute_with_plant_until(
    text: &str,
    out: &Path,
    shift: u32,
    plant: Box<dyn cosim::Plant + Send>,
    ac_enabled: bool,
    acs: &millac::ac::AcSettings,
    tools: &millac::gcode::tools::ToolTable,
    stop: Option<Stop>,
) -> Result<(Capture, Vec<cosim::Exchange>)> {
    let mut spec = prepare(text, out, shift)?;
    spec.stop = stop;
    let _ = std::fs::remove_file(out.join(cosim::AC_LOG));
    let _record = RunSettings::write(out, acs, tools)?;
    let bridge = cosim::Bridge::start(out, plant, acs.sample_hz, ac_enabled)?;
    let cap = run_capture(&spec);
    let exchanges = bridge.finish();
    let cap = cap?;
    // A bridge that failed is an ADC that went away: the firmware holds and reports it (see
    // `millac::rt::ac`), so the run is a result; its exchanges are lost with the bridge.
    let exchanges = exchanges.unwrap_or_else(|e| {
        eprintln!("millac: the simulated ADC failed: {e:#}");
        Vec::new()
    });
    Ok((cap, exchanges))
}

pub fn stats(v: &[u64]) -> Value {
    let mut s = v.to_vec();
    s.sort_unstable();
    match (s.first(), s.last()) {
        (Some(&min), Some(&max)) => json!({"min": min, "median": s[s.len() / 2], "max": max}),
        _ => Value::Null,
    }
}

/// Pre-checks, runs and analyses a program; writes out/capture.vcd and out/summary.json.
pub fn run(text: &str, out: &Path, shift: u32) -> Result<Outcome> {
    run_with(text, out, shift, None)
}

/// A run against the simulated cutting process: the firmware's ADC reads come from `cut` in
/// lockstep; `ac` applies the controller's feed cap (false: measure and log only, `--no-ac`);
/// `faults` are injected into the codes the firmware reads (`--fault`, see [`crate::host::fault`]);
/// `settings` are the AC settings of the run (`--strategy`), the same for the firmware (a
/// settings record in the run directory when they are not the defaults) and for the host's
/// report and replay.
#[derive(Clone, Debug)]
pub struct AcRun {
    pub cut: crate::host::acsim::Cut,
    pub ac: bool,
    pub faults: Vec<crate::host::fault::Fault>,
    pub settings: millac::ac::AcSettings,
}

/// The cutting process as the firmware's simulated ADC; keeps the true force and torque of every
/// sample for the report.
struct ProcessPlant {
    process: millac_plant::Process,
    truth: std::sync::Arc<std::sync::Mutex<Vec<(f64, f64)>>>,
    /// The program's tool changes still to come, in order (`Cut::changes`).
    changes: std::collections::VecDeque<crate::host::acsim::ToolChangeAt>,
    /// The tool cutting (0: the cut's own, before any M6), and the stock as each tool left it
    /// (a multi-tool cut's: at each change, and when the plant is dropped at the run's end).
    tool: u8,
    stocks: Stocks,
}

/// The stocks a multi-tool run's plant leaves, one per tool (kept by the co-simulated plant).
pub type Stocks = std::sync::Arc<std::sync::Mutex<Vec<(u8, millac_plant::Stock)>>>;

impl ProcessPlant {
    /// Keeps the stock as the tool cutting left it (a tool fitted by an M6).
    fn keep_stock(&mut self) {
        if self.tool != 0 {
            if let Ok(mut v) = self.stocks.lock() {
                v.push((self.tool, self.process.stock().clone()));
            }
        }
    }
}

impl Drop for ProcessPlant {
    fn drop(&mut self) {
        self.keep_stock();
    }
}

impl cosim::Plant for ProcessPlant {
    fn sample(&mut self, _index: u32, t_s: f64, pos_blu: [i64; 3]) -> Option<[u16; 3]> {
        crate::progress::clock(t_s);
        let s = self.process.sample(t_s, pos_blu);
        if let Ok(mut v) = self.truth.lock() {
            v.push((s.f_true_n, s.t_true_nm));
        }
        Some(s.codes)
    }

    fn spindle_rpm(&mut self, rpm: u32) -> Result<()> {
        self.process
            .set_spindle_rpm(f64::from(rpm))
            .map_err(|e| anyhow::anyhow!("spindle S{rpm}: {}", e.0))
    }

    /// The firmware's M6: the program's next tool change, which fits this tool (the tool and
    /// speed the host's run takes there, `Cut::with_tool_changes`).
    fn tool(&mut self, tool: u8) -> Result<()> {
        let c = self
            .changes
            .pop_front()
            .filter(|c| c.fitted.number == tool)
            .ok_or_else(|| {
                anyhow::anyhow!("the firmware fitted T{tool}, not the program's next tool change")
            })?;
        self.keep_stock();
        self.tool = tool;
        self.process
            .change_tool(c.plant, c.rpm)
            .map_err(|e| anyhow::anyhow!("T{tool} at line {}: {}", c.line, e.0))
    }

    fn sound(&mut self) -> [u16; millac::wire::SOUND_PER_SAMPLE] {
        self.process
            .take_sound_block()
            .unwrap_or([millac::wire::NO_SOUND; millac::wire::SOUND_PER_SAMPLE])
    }
}

/// The cutting process of `a` as the firmware's simulated ADC, with `a`'s faults injected (the
/// same code as the host's `--fault`), keeping the true force and torque of every sample in `truth`.
pub fn plant_with_truth(
    a: &AcRun,
    truth: std::sync::Arc<std::sync::Mutex<Vec<(f64, f64)>>>,
    stocks: Stocks,
) -> Result<Box<dyn cosim::Plant + Send>> {
    let plant = ProcessPlant {
        process: a.cut.process()?,
        truth,
        changes: a.cut.changes.iter().copied().collect(),
        tool: 0,
        stocks,
    };
    let acs = a.settings;
    let zero = acs.cal.map(|c| f64::from(c.offset));
    Ok(Box::new(crate::host::fault::Faulty::new(
        plant,
        &a.faults,
        zero,
        acs.sample_hz,
    )))
}

/// [`plant_with_truth`] without the record of the truth.
pub fn process_plant(a: &AcRun) -> Result<Box<dyn cosim::Plant + Send>> {
    plant_with_truth(a, Default::default(), Default::default())
}

/// A program rejected before anything ran: the 1-based line and the message (`line N: ...`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rejected {
    pub line: u32,
    pub message: String,
}

/// The text of a program file, or its rejection at the first byte that is not UTF-8 (the line
/// that holds it, and its byte column on that line, both 1-based).
pub fn program_text(bytes: &[u8]) -> Result<&str, Rejected> {
    std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        let before = &bytes[..at];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let column = at
            - before
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1)
            + 1;
        let line = u32::try_from(line).unwrap_or(u32::MAX);
        Rejected {
            line,
            message: format!(
                "line {line}: not UTF-8 (byte 0x{:02x} at column {column})",
                bytes[at]
            ),
        }
    })
}

/// Writes `out/summary.json` with `error` {`line`, `message`} for a program rejected before
/// anything ran, says so on stderr and returns the summary.
pub fn write_rejection(out: &Path, r: &Rejected) -> Result<Value> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let summary = json!({"error": {"line": r.line, "message": r.message}});
    write_json(&out.join("summary.json"), &summary)?;
    eprintln!("millac: program rejected, nothing was run: {}", r.message);
    Ok(summary)
}

/// A flag that stops a run early ([`run_until`]).
pub type Stop = std::sync::Arc<std::sync::atomic::AtomicBool>;

/// Pre-checks, runs (optionally against the cutting process) and analyses a program.
pub fn run_with(text: &str, out: &Path, shift: u32, ac: Option<&AcRun>) -> Result<Outcome> {
    run_until(text, out, shift, ac, None)
}

/// [`run_with`], stopped early when `stop` is set (the host tool sets it on SIGINT and SIGTERM,
/// [`crate::interrupt`]): QEMU is stopped cleanly and what ran is reported like a hold, under
/// `interrupted` (`signal`, the line that was running, the blocks done, the position), with
/// `completed` false and the capture of what ran in capture.vcd.
pub fn run_until(
    text: &str,
    out: &Path,
    shift: u32,
    ac: Option<&AcRun>,
    stop: Option<Stop>,
) -> Result<Outcome> {
    let settings = Settings::default();
    settings
        .validate(&millac::settings::BoardLimits::GENERIC)
        .map_err(|e| anyhow::anyhow!("settings: {}", e.message()))?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let prog = match analysis::load_program(text, &settings) {
        Ok(p) => p,
        Err(e) => {
            let summary = write_rejection(
                out,
                &Rejected {
                    line: e.line(),
                    message: e.to_string(),
                },
            )?;
            return Ok(Outcome {
                summary,
                report: None,
                capture: None,
                ok: false,
                exchanges: Vec::new(),
                ac_log: Vec::new(),
            });
        }
    };
    let truth = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let stocks = Stocks::default();
    let (cap, exchanges) = match ac {
        None => (execute_until(text, out, shift, stop.clone())?, Vec::new()),
        Some(a) => {
            let plant = plant_with_truth(a, truth.clone(), stocks.clone())?;
            let tools = &a.cut.tools;
            execute_with_plant_until(
                text,
                out,
                shift,
                plant,
                a.ac,
                &a.settings,
                tools,
                stop.clone(),
            )?
        }
    };
    // A hold the firmware reported is a result (the run did not complete), anything else that
    // ends the firmware with failure is not; nor is a run stopped by a signal, reported with what
    // ran (the blocks that ran to their end in the capture).
    let interrupted = stop
        .as_ref()
        .is_some_and(|s| s.load(std::sync::atomic::Ordering::SeqCst))
        && !cap.result.lines().any(|l| l.starts_with("millac: "));
    let hold = if interrupted {
        let ran = analysis::analyse(&prog, &settings, 0, &cap.pins);
        Some(Hold {
            alarm: String::new(),
            blocks_done: ran.blocks.iter().take_while(|b| b.completed).count(),
            position: vcd::positions(0, &cap.pins),
            signal: Some(
                crate::interrupt::received()
                    .map_or_else(|| "a stop request".into(), crate::interrupt::name),
            ),
        })
    } else {
        firmware_hold(&cap.result)
    };
    if cap.status != Some(0) && hold.is_none() {
        anyhow::bail!(
            "firmware exited with {:?}: {}\nfirmware log:\n{}{}",
            cap.status,
            cap.result.trim_end(),
            cap.stdout,
            cap.stderr
        );
    }
    vcd::write_vcd(&out.join("capture.vcd"), 0, &cap.pins, Some(cap.end_ns))?;
    let truth = truth.lock().map(|v| v.clone()).unwrap_or_default();
    let stocks = stocks.lock().map(|v| v.clone()).unwrap_or_default();
    let ac_in = ac.map(|a| AcInput {
        run: a,
        samples: exchanges.len(),
        truth: &truth,
        stocks: &stocks,
    });
    let (summary, report, records) =
        summarise(&prog, &settings, &cap, out, shift, hold.as_ref(), ac_in)?;
    let fw = firmware_position(&cap.result);
    write_json(&out.join("summary.json"), &summary)?;
    let ok = checks_pass(&report) && fw == Some(report.final_position) && hold.is_none();
    Ok(Outcome {
        summary,
        report: Some(report),
        capture: Some(cap),
        ok,
        exchanges,
        ac_log: records,
    })
}

/// What the AC side of a run adds to its summary: the run's cut, the samples exchanged and the
/// true force and torque of every sample.
pub struct AcInput<'a> {
    pub run: &'a AcRun,
    pub samples: usize,
    pub truth: &'a [(f64, f64)],
    /// The stock as each tool of a multi-tool run left it (empty otherwise).
    pub stocks: &'a [(u8, millac_plant::Stock)],
}

/// Analyses the capture of `prog` and builds summary.json (the stable keys, docs/user/getting-started.md), and with
/// `ac` writes `out/ac.csv` and `out/ac.svg` from `out/ac.log` and prints the comparison table.
/// `run` and `serve` (a session replayed from its log) both report through it, so their keys
/// are the same. Returns the summary, the report and the AC log's records.
pub fn summarise(
    prog: &[ProgBlock],
    settings: &Settings,
    cap: &Capture,
    out: &Path,
    shift: u32,
    hold: Option<&Hold>,
    ac: Option<AcInput>,
) -> Result<(Value, Report, Vec<cosim::AcRecord>)> {
    let done = hold.map_or(prog.len(), |h| h.blocks_done);
    let mut report = analysis::analyse_until(prog, settings, 0, &cap.pins, done);
    let e = analysis::edges(0, &cap.pins);
    let feed_capped = ac.as_ref().is_some_and(|a| a.run.ac);
    // With the feed cap applied the pulses follow the controller, not the programmed feeds.
    report.pulses_match_host =
        (!feed_capped).then(|| analysis::compare_with_host(prog, settings, &e.groups).is_none());
    let fw = firmware_position(&cap.result);
    let mut summary = summary_json(prog, &report);
    if feed_capped {
        summary["max_feed_error_pct"] = Value::Null;
    }
    let mut pulses = [0u64; 3];
    for edge in &e.edges {
        pulses[edge.axis] += 1;
    }
    summary["pulses"] = json!({"x": pulses[0], "y": pulses[1], "z": pulses[2]});
    summary["frame_instructions"] = stats(&cap.handlers[0].1);
    summary["pulse_end_instructions"] = stats(&cap.handlers[1].1);
    summary["frames"] = json!(cap.handlers[0].1.len());
    summary["firmware_position_blu"] = json!(fw.map(|p| json!({"x": p[0], "y": p[1], "z": p[2]})));
    summary["icount_shift"] = json!(shift);
    summary["completed"] = json!(hold.is_none());
    if let Some(h) = hold {
        let key = if h.signal.is_some() {
            "interrupted"
        } else {
            "hold"
        };
        summary[key] = hold_json(prog, h);
        eprintln!("millac: {}", not_finished(prog, h));
    }
    let mut records = Vec::new();
    if let Some(a) = ac {
        let log = std::fs::read_to_string(out.join(cosim::AC_LOG)).unwrap_or_default();
        records = cosim::parse_ac_log(&log)?;
        let acs = a.run.settings;
        let rows = ac_rows(settings, &acs, &records, a.truth);
        let csv = out.join("ac.csv");
        std::fs::write(&csv, crate::host::acsim::csv(&rows))
            .with_context(|| format!("writing {}", csv.display()))?;
        crate::evaluation::acreport::plot_against(&out.join("ac.svg"), &rows, &acs, settings)?;
        let period_tools: Vec<u8> = records.iter().map(|r| r.tool).collect();
        let load = crate::host::acsim::load_figures_by_tool(
            a.truth,
            &period_tools,
            acs.samples_per_period() as usize,
            &a.run.cut,
            acs.optimal_fraction as f64,
            acs.sample_hz,
        );
        let cmp = crate::evaluation::acreport::compare(prog, settings, &a.run.cut, &acs)?;
        summary["ac"] = crate::evaluation::acreport::ac_json(report.machining_time_s, &load, &cmp);
        summary["ac"]["enabled"] = json!(a.run.ac);
        summary["ac"]["strategy"] = json!(acs.strategy.name());
        summary["ac"]["samples"] = json!(a.samples);
        summary["ac"]["holds"] = json!(records.iter().filter(|r| r.hold.is_some()).count());
        summary["ac"]["overruns"] = json!(records.last().map_or(0, |r| r.overruns));
        let why = hold.map(|h| held_at(prog, h));
        crate::evaluation::acreport::print_table(
            report.machining_time_s,
            &load,
            &cmp,
            why.as_deref(),
            acs.strategy,
        );
        // Each tool's part: the AFC log and its figure, as `host` writes them.
        let blocks: Vec<(u64, u64, Option<f64>)> = report
            .blocks
            .iter()
            .map(|b| (b.t_start_ns, b.t_end_ns, b.feed.map(|f| f.0)))
            .collect();
        let tools = crate::host::acsim::tool_runs_of_periods(
            &rows,
            a.truth,
            acs.samples_per_period() as usize,
            &a.run.cut,
            &blocks,
            done,
            &acs,
            acs.optimal_fraction as f64,
        );
        let log = crate::evaluation::acreport::tool_log(&tools, &cmp);
        if !log.is_empty() {
            crate::evaluation::acreport::print_tool_log(&log);
            summary["tools"] = json!(log);
        }
        let figures =
            crate::evaluation::acreport::plot_tools(out, &rows, &a.run.cut, &acs, settings)?;
        crate::evaluation::acreport::print_figures(out, &figures);
        crate::evaluation::heightmap::write_tool_stocks(out, a.stocks)?;
    }
    Ok((summary, report, records))
}

/// ac.csv rows from the firmware's log (one record per AC period, encoder positions) and the true
/// force and torque of every sample (period k holds samples 10k .. 10k + 9).
pub fn ac_rows(
    settings: &Settings,
    acs: &millac::ac::AcSettings,
    records: &[cosim::AcRecord],
    truth: &[(f64, f64)],
) -> Vec<crate::host::acsim::AcRow> {
    let per = acs.samples_per_period() as usize;
    let mut prev = [0i64; 3];
    records
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let win = truth
                .get(k * per..((k + 1) * per).min(truth.len()))
                .unwrap_or(&[]);
            let d = [0, 1, 2].map(|i| r.pos_blu[i] - prev[i]);
            prev = r.pos_blu;
            crate::host::acsim::AcRow {
                t_ms: r.t_ms,
                pos_blu: r.pos_blu,
                feed_ipm: crate::host::acsim::path_feed_ipm(settings, d, acs.period_ms),
                f_meas_n: r.f_n as f64,
                t_meas_nm: r.t_nm as f64,
                f_true_n: win.iter().map(|s| s.0).fold(0.0, f64::max),
                t_true_nm: win.iter().map(|s| s.1.abs()).fold(0.0, f64::max),
                e: r.e as f64,
                state: r
                    .hold
                    .as_ref()
                    .map_or("run".to_string(), |h| format!("hold:{h}")),
                feed_cap: r.feed_cap,
                estimates: None,
                tool: r.tool,
            }
        })
        .collect()
}

pub fn checks_pass(r: &Report) -> bool {
    r.end_points_exact() && r.pulses_match_host != Some(false)
}

/// A hold that stopped a run: the adaptive controller's alarm, the blocks completed (the next
/// one was running) and the exact position.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Hold {
    pub alarm: String,
    pub blocks_done: usize,
    pub position: [i64; 3],
    /// Not a hold of the firmware: the run was stopped by this signal (`SIGINT`, `SIGTERM`).
    pub signal: Option<String>,
}

/// The firmware's report of a hold in its result file ([`Capture::result`]): `alarm: <text>`
/// (the first one) and `millac: hold blocks=N position=x,y,z`; None when the firmware did not stop
/// on a hold.
pub fn firmware_hold(result: &str) -> Option<Hold> {
    let line = result
        .lines()
        .find_map(|l| l.strip_prefix("millac: hold "))?;
    let blocks_done = line
        .split_whitespace()
        .find_map(|w| w.strip_prefix("blocks="))?
        .parse()
        .ok()?;
    let alarm = result
        .lines()
        .find_map(|l| l.strip_prefix("alarm: "))
        .unwrap_or("")
        .to_string();
    Some(Hold {
        alarm,
        blocks_done,
        position: firmware_position(result)?,
        signal: None,
    })
}

/// `held at line N` (the program line of the block that was running; `stopped by SIGINT at line
/// N` for a run a signal stopped).
pub fn held_at(prog: &[ProgBlock], h: &Hold) -> String {
    let verb = match &h.signal {
        Some(s) => format!("stopped by {s}"),
        None => "held".to_string(),
    };
    match prog.get(h.blocks_done) {
        Some(b) => format!("{verb} at line {}", b.block.line),
        None => format!("{verb} after the last block"),
    }
}

fn not_finished(prog: &[ProgBlock], h: &Hold) -> String {
    let [x, y, z] = h.position;
    let why = if h.alarm.is_empty() {
        String::new()
    } else {
        format!(": {}", h.alarm)
    };
    format!(
        "the program did not finish: {} (position {x},{y},{z} BLU){why}",
        held_at(prog, h)
    )
}

/// summary.json's `hold`: the alarm, the line of the running block (`block`, null after the last
/// block), the blocks completed and the position. For a run a signal stopped, `interrupted`'s
/// value: `signal` instead of `alarm`.
pub fn hold_json(prog: &[ProgBlock], h: &Hold) -> Value {
    let [x, y, z] = h.position;
    let mut v = json!({
        "alarm": h.alarm,
        "block": prog.get(h.blocks_done).map(|b| b.block.line),
        "blocks_done": h.blocks_done,
        "position_blu": {"x": x, "y": y, "z": z},
    });
    if let Some(s) = &h.signal {
        v["signal"] = json!(s);
        if let Some(o) = v.as_object_mut() {
            o.remove("alarm");
        }
    }
    v
}

/// The final (or held) position in the firmware's result file ([`Capture::result`]):
/// `millac: blocks=N position=x,y,z` or `millac: hold ...`.
pub fn firmware_position(result: &str) -> Option<[i64; 3]> {
    let line = result.lines().find_map(|l| l.strip_prefix("millac: "))?;
    let pos = line
        .split_whitespace()
        .find_map(|w| w.strip_prefix("position="))?;
    let v: Vec<i64> = pos.split(',').filter_map(|s| s.parse().ok()).collect();
    (v.len() == 3).then(|| [v[0], v[1], v[2]])
}

pub fn summary_json(prog: &[ProgBlock], r: &Report) -> Value {
    let [x, y, z] = r.final_position;
    json!({
        "blocks": prog.len(),
        "machining_time_s": (r.machining_time_s * 1e6).round() / 1e6,
        "final_position_blu": {"x": x, "y": y, "z": z},
        "max_deviation_blu": (r.max_deviation_blu * 1000.0).round() / 1000.0,
        "max_feed_error_pct": (r.max_feed_error_pct * 1000.0).round() / 1000.0,
        "min_pulse_width_ns": r.min_pulse_width_ns,
        "min_sign_setup_ns": r.min_sign_setup_ns,
        "end_points_exact": r.end_points_exact(),
        "pulses_match_host": r.pulses_match_host,
    })
}

/// Writes `v` as pretty JSON. A file that could not be written whole (a full disk) is removed:
/// no cut or earlier report is left under the name.
pub fn write_json(path: &Path, v: &Value) -> Result<()> {
    let mut s = serde_json::to_string_pretty(v)?;
    s.push('\n');
    std::fs::write(path, s).map_err(|e| {
        if !path.is_dir() {
            let _ = std::fs::remove_file(path);
        }
        anyhow::Error::new(e).context(format!("writing {}", path.display()))
    })
}

pub fn print_summary(s: &Value, out: &Path) {
    println!("  blocks              {}", s["blocks"]);
    println!("  machining time      {} s", s["machining_time_s"]);
    println!("  final position BLU  {}", s["final_position_blu"]);
    if let Some(h) = s.get("hold") {
        println!(
            "  did not finish      held at line {} ({} blocks done) at {}: {}",
            h["block"], h["blocks_done"], h["position_blu"], h["alarm"]
        );
    }
    let compared = match &s["pulses_match_host"] {
        Value::Null => "not compared (the feed follows the AC)".to_string(),
        v => v.to_string(),
    };
    println!(
        "  end points exact    {}   pulses equal host core: {compared}",
        s["end_points_exact"]
    );
    println!("  max deviation       {} BLU", s["max_deviation_blu"]);
    match &s["max_feed_error_pct"] {
        Value::Null => println!("  max feed error      n/a (the AC sets the feed)"),
        v => println!("  max feed error      {v} %"),
    }
    println!(
        "  min pulse width     {} ns   min sign setup {} ns",
        s["min_pulse_width_ns"], s["min_sign_setup_ns"]
    );
    println!(
        "  frame ISR instr.    {}   pulse-end ISR {}",
        s["frame_instructions"], s["pulse_end_instructions"]
    );
    println!(
        "  wrote {}/capture.vcd and {}/summary.json",
        out.display(),
        out.display()
    );
    if s.get("ac").is_some() {
        println!(
            "  wrote {}/ac.csv and {}/ac.svg (feed, F/F0, T/T0 against time; the path coloured by feed)",
            out.display(),
            out.display()
        );
    }
}
