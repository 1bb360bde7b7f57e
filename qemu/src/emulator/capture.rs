//! Virtual logic analyser capture (host): runs the firmware under QEMU (lm3s6965evb, icount) with the
//! millac TCG plugin and the `pl061_write` trace event, and turns the GPIO port B writes into timed
//! pin events plus per-interrupt-handler instruction counts. The Nucleo-F446RE firmware (its `qemu`
//! feature) runs the same way on netduinoplus2 ([`Machine::Netduinoplus2`]): there the values of
//! the GPIOC BSRR stores come from QEMU's `-d unimp` log instead of a trace event.
//!
//! Measured on Debian's QEMU 7.2:
//! - plugin arguments are given as `-plugin lib.so,key=value,key=value` (the older
//!   `arg=key=value` form also works but prints a deprecation warning);
//! - `-trace pl061_write -D FILE` writes one line per PL061 register write, in execution order:
//!   `pl061_write /machine/unattached/device[9] offset 0x4 value 0x1` (no timestamp; with
//!   `-msg timestamp=on` a `PID@SECS:` prefix is added, which the parser tolerates);
//! - on a semihosting SYS_EXIT QEMU calls exit(), and the plugin's atexit callback runs (its final
//!   `e COUNT` line is present), for exit status 0 and 1 alike.
//! - QEMU 7.2 calls memory callbacks registered for `QEMU_PLUGIN_MEM_W` on loads too: the plugin
//!   filters with `qemu_plugin_mem_is_store` (without it the zip fails on the firmware's
//!   read-modify-write of GPIODIR).
//!
//! The plugin sees store addresses but not values (plugin API v1); the trace sees offsets and values
//! but not the time. Both list the same writes in the same order, so they are zipped one to one (the
//! offsets must agree, else the capture fails) and the port B writes are replayed like QEMU's PL061
//! (data writes are masked by address bits \[9:2\] and by the direction register). Pin levels reported
//! are `data & dir` (input pins read 0). Time of a write = (instructions executed up to and including
//! the store) << shift, in ns; exact under `-icount shift=N,sleep=off` with a busy idle loop.
use anyhow::{bail, ensure, Context, Result};
use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// GPIO port bases of the lm3s6965 (ports A-G): all are watched so that trace and plugin records
/// can be zipped even when the firmware writes other ports.
pub const LM3S6965_GPIO_BASES: [u32; 7] = [
    0x4000_4000,
    0x4000_5000,
    0x4000_6000,
    0x4000_7000,
    0x4002_4000,
    0x4002_5000,
    0x4002_6000,
];
/// GPIO port B, the step/sign pins.
pub const PORT_B: u32 = 0x4000_5000;
/// Sub-directory of the run directory that receives the plugin, its log and the trace.
pub const CAPTURE_DIR: &str = ".millac-capture";

/// The QEMU machine a capture runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Machine {
    /// lm3s6965evb (the QEMU board): PL061 GPIO, values from the `pl061_write` trace.
    Lm3s6965,
    /// netduinoplus2 (STM32F405, Cortex-M4) running the Nucleo-F446RE firmware built with its
    /// `qemu` feature: QEMU 7.2 models no GPIO there, so GPIO stores go to unimplemented devices
    /// whose `-d unimp` log lines (`GPIOC: unimplemented device write (size 4, offset 0x018, value
    /// 0x...)`) carry the values; the pins are PC4..PC9 written through BSRR (see [`F4_GPIOC`]).
    Netduinoplus2,
}

/// GPIO port C of the STM32F4 (PC4..PC9: X, Y, Z PULSE, X, Y, Z SIGN).
pub const F4_GPIOC: u32 = 0x4002_0800;
/// First STM32F4 GPIO port (GPIOA); ports A..I follow every 0x400 bytes.
pub const F4_GPIOA: u32 = 0x4002_0000;
/// First pin of the six on port C (PC4).
pub const F4_FIRST_PIN: u32 = 4;

/// An interrupt handler to time: entry PC and return-instruction PCs (Thumb bit cleared).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HandlerSpec {
    pub name: String,
    pub entry: u32,
    pub exits: Vec<u32>,
}

impl HandlerSpec {
    /// Looks the function `name` up in the ELF (see [`crate::emulator::elf::find_function`]).
    pub fn from_elf(elf: &Path, name: &str) -> Result<HandlerSpec> {
        let f = crate::emulator::elf::find_function(elf, name)?;
        ensure!(
            !f.returns.is_empty(),
            "no return instruction found in `{name}`"
        );
        Ok(HandlerSpec {
            name: f.name,
            entry: f.addr,
            exits: f.returns,
        })
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct CaptureSpec {
    /// Firmware ELF.
    pub elf: PathBuf,
    /// Working directory of QEMU (the firmware reads `program.nc` there through semihosting).
    pub run_dir: PathBuf,
    /// `-icount shift=N`: one instruction = 2^N ns.
    pub icount_shift: u32,
    /// Extra QEMU arguments, appended last.
    pub extra_args: Vec<String>,
    /// Handlers to time (at most 16).
    pub handlers: Vec<HandlerSpec>,
    /// Wall-clock limit; QEMU is killed and the capture fails past it (`Duration::MAX`: none).
    pub timeout: Duration,
    /// GPIO blocks watched by the plugin (must cover every PL061 the firmware writes).
    pub gpio_ports: Vec<u32>,
    /// The port whose pins are reported.
    pub pin_port: u32,
    /// Set to stop the run (`serve`, an interrupted `run`): QEMU gets SIGTERM, shuts down cleanly
    /// (the plugin writes its log) and the capture is what ran until then.
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// The machine (default lm3s6965evb).
    pub machine: Machine,
    /// (handler index, instructions): trace the PCs of every call of that handler longer than
    /// that ([`Capture::traces`]; every instruction then gets a plugin callback, so the run is
    /// slower, its counts unchanged). None: no trace.
    pub trace: Option<(usize, u64)>,
}

impl CaptureSpec {
    /// Defaults: shift 4 (16 ns per instruction), no handlers, 120 s timeout, lm3s6965 ports, port B.
    pub fn new(elf: impl Into<PathBuf>, run_dir: impl Into<PathBuf>) -> CaptureSpec {
        CaptureSpec {
            elf: elf.into(),
            run_dir: run_dir.into(),
            icount_shift: 4,
            extra_args: Vec::new(),
            handlers: Vec::new(),
            timeout: Duration::from_secs(120),
            gpio_ports: LM3S6965_GPIO_BASES.to_vec(),
            pin_port: PORT_B,
            stop: None,
            machine: Machine::Lm3s6965,
            trace: None,
        }
    }

    /// The Nucleo-F446RE firmware (`qemu` feature) on netduinoplus2: GPIOC watched, its PC4..PC9
    /// reported.
    pub fn netduinoplus2(elf: impl Into<PathBuf>, run_dir: impl Into<PathBuf>) -> CaptureSpec {
        CaptureSpec {
            gpio_ports: vec![F4_GPIOC],
            pin_port: F4_GPIOC,
            machine: Machine::Netduinoplus2,
            ..CaptureSpec::new(elf, run_dir)
        }
    }
}

/// Result of a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Capture {
    /// (time ns, PB0..PB7 levels after the write) for each write that changed a pin; initial 0.
    pub pins: Vec<(u64, u8)>,
    /// Per handler (same order as the spec): instructions from entry to return, inclusive, per call.
    pub handlers: Vec<(String, Vec<u64>)>,
    /// Per handler, per call (as in `handlers`): the virtual time of its entry instruction, ns
    /// (its instruction count << shift, as the pins' times).
    pub handler_starts: Vec<Vec<u64>>,
    /// The traced calls ([`CaptureSpec::trace`]), in order.
    pub traces: Vec<HandlerTrace>,
    /// Total instructions executed.
    pub total_instructions: u64,
    /// Virtual time at exit, ns.
    pub end_ns: u64,
    /// The firmware's log: QEMU's stdout, its defmt frames decoded with the ELF's table, one
    /// `<level>: <message>` line each ([`crate::emulator::defmtlog`]; as text for an ELF without a table).
    /// For people: what the tools read is in [`Capture::result`].
    pub stdout: String,
    /// The firmware's result file ([`crate::lm3s_files::RESULT_NAME`] in the run directory, written
    /// through semihosting): errors, alarms and the final position, the lines the tools parse
    /// (see `millac::wire`, "Result file"); empty when the firmware wrote none.
    pub result: String,
    /// QEMU's stderr.
    pub stderr: String,
    /// QEMU's exit status (the firmware's semihosting exit code), None if killed by a signal.
    pub status: Option<i32>,
}

/// One traced handler call: the PCs it executed, entry to return.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HandlerTrace {
    /// Index of the handler in the spec.
    pub handler: usize,
    /// Virtual time of its entry instruction, ns.
    pub start_ns: u64,
    /// The PCs executed, in order (at most 1024; the call's count is in `handlers`).
    pub pcs: Vec<u32>,
}

/// Parsed plugin output.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PluginLog {
    /// (instruction count, address) of each store to a watched GPIO block.
    pub stores: Vec<(u64, u32)>,
    /// (handler index, instructions, instruction count at its entry) per completed handler
    /// invocation.
    pub handlers: Vec<(usize, u64, u64)>,
    /// (handler index, instruction count at its entry, PCs) per traced invocation.
    pub traces: Vec<(usize, u64, Vec<u32>)>,
    /// Total instruction count, from the final line written at exit.
    pub total: Option<u64>,
}

/// One `pl061_write` trace event.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TraceWrite {
    /// Device path (may be empty if the QEMU build does not print one).
    pub device: String,
    pub offset: u32,
    pub value: u32,
}

/// A GPIO write with its time and value: a plugin store zipped with its trace event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpioWrite {
    pub count: u64,
    pub addr: u32,
    pub value: u32,
}

fn hex(s: &str) -> Result<u64> {
    let s = s.trim_start_matches("0x");
    u64::from_str_radix(s, 16).with_context(|| format!("bad hex number `{s}`"))
}

/// Parses the plugin's text output (`s COUNT ADDR`, `h K INSNS START`, `t K START PC...`,
/// `e COUNT`, all hex).
pub fn parse_plugin_log(text: &str) -> Result<PluginLog> {
    let mut log = PluginLog::default();
    for (n, line) in text.lines().enumerate() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let parsed: Result<()> = (|| {
            match f.as_slice() {
                ["s", c, a] => log.stores.push((hex(c)?, hex(a)? as u32)),
                ["h", k, i, c] => log.handlers.push((hex(k)? as usize, hex(i)?, hex(c)?)),
                ["t", k, c, pcs @ ..] => log.traces.push((
                    hex(k)? as usize,
                    hex(c)?,
                    pcs.iter()
                        .map(|p| Ok(hex(p)? as u32))
                        .collect::<Result<_>>()?,
                )),
                ["e", c] => log.total = Some(hex(c)?),
                _ => bail!("unexpected line"),
            }
            Ok(())
        })();
        parsed.with_context(|| format!("plugin log line {}: `{line}`", n + 1))?;
    }
    Ok(log)
}

/// Parses the `pl061_write` lines of a QEMU trace log (other lines are ignored).
pub fn parse_trace(text: &str) -> Result<Vec<TraceWrite>> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let Some(pos) = line.find("pl061_write ") else {
            continue;
        };
        let f: Vec<&str> = line[pos + "pl061_write ".len()..]
            .split_whitespace()
            .collect();
        let w = (|| {
            let o = f
                .iter()
                .position(|t| *t == "offset")
                .context("no `offset`")?;
            let v = f.iter().position(|t| *t == "value").context("no `value`")?;
            Ok::<_, anyhow::Error>(TraceWrite {
                device: f[..o].join(" "),
                offset: hex(f.get(o + 1).context("no offset value")?)? as u32,
                value: hex(f.get(v + 1).context("no value")?)? as u32,
            })
        })()
        .with_context(|| format!("trace line {}: `{line}`", n + 1))?;
        out.push(w);
    }
    Ok(out)
}

/// Parses the GPIO writes of a QEMU `-d unimp` log of netduinoplus2 (other lines are ignored):
/// `GPIOC: unimplemented device write (size 4, offset 0x018, value 0x03800000)` becomes a
/// [`TraceWrite`] with device `GPIOC` and the offset within that port.
pub fn parse_unimp_gpio(text: &str) -> Result<Vec<TraceWrite>> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let Some(rest) = line.strip_prefix("GPIO") else {
            continue;
        };
        let Some((port, rest)) = rest.split_once(": unimplemented device write (") else {
            continue;
        };
        let w = (|| {
            let field = |key: &str| -> Result<u32> {
                let v = rest
                    .split(", ")
                    .find_map(|f| f.strip_prefix(key))
                    .with_context(|| format!("no `{key}`"))?;
                Ok(hex(v.trim_end_matches(')'))? as u32)
            };
            Ok::<_, anyhow::Error>(TraceWrite {
                device: format!("GPIO{port}"),
                offset: field("offset ")?,
                value: field("value ")?,
            })
        })()
        .with_context(|| format!("unimp log line {}: `{line}`", n + 1))?;
        out.push(w);
    }
    Ok(out)
}

/// The address of an STM32F4 GPIO write parsed by [`parse_unimp_gpio`] (`GPIOA` .. `GPIOI`).
pub fn f4_gpio_address(w: &TraceWrite) -> Option<u32> {
    let letter = w.device.strip_prefix("GPIO")?.chars().next()?;
    let k = (letter as u32).checked_sub('A' as u32).filter(|k| *k < 9)?;
    Some(F4_GPIOA + 0x400 * k + w.offset)
}

/// Zips plugin store records with the writes of an unimp log, one to one in order, keeping the
/// log's writes inside the watched 4 KiB windows. Fails if the counts differ or a pair's
/// addresses disagree.
pub fn zip_f4_writes(
    stores: &[(u64, u32)],
    writes: &[TraceWrite],
    watched: &[u32],
) -> Result<Vec<GpioWrite>> {
    let mut log = Vec::new();
    for w in writes {
        let a = f4_gpio_address(w).with_context(|| format!("GPIO device `{}`", w.device))?;
        if watched.iter().any(|&b| a >= b && a < b + 0x1000) {
            log.push((a, w.value));
        }
    }
    ensure!(
        stores.len() == log.len(),
        "plugin saw {} GPIO stores but the unimp log has {} GPIO writes",
        stores.len(),
        log.len()
    );
    stores
        .iter()
        .zip(log)
        .enumerate()
        .map(|(i, (&(count, addr), (a, value)))| {
            ensure!(
                addr == a,
                "write #{i}: plugin store at {addr:#x} (count {count}) but the log's at {a:#x}"
            );
            Ok(GpioWrite { count, addr, value })
        })
        .collect()
}

/// Replays the writes to an STM32F4 GPIO port's BSRR (set bits in the low half, reset bits in
/// the high half; set wins) and ODR and returns (time ns, the six pins from `first_pin`) after
/// each write that changed them; time = count << shift.
pub fn replay_bsrr(writes: &[GpioWrite], port: u32, first_pin: u32, shift: u32) -> Vec<(u64, u8)> {
    let (mut odr, mut pins) = (0u32, 0u8);
    let mut out = Vec::new();
    for w in writes {
        match w.addr.wrapping_sub(port) {
            0x14 => odr = w.value & 0xFFFF,
            0x18 => odr = (odr & !(w.value >> 16)) | (w.value & 0xFFFF),
            _ => continue,
        }
        let now = ((odr >> first_pin) & 0b11_1111) as u8;
        if now != pins {
            pins = now;
            out.push((w.count << shift, pins));
        }
    }
    out
}

/// Zips plugin store records with trace events, one to one in order. Fails if the counts differ or a
/// pair's offsets disagree, or if one trace device maps to two GPIO blocks.
pub fn zip_writes(stores: &[(u64, u32)], writes: &[TraceWrite]) -> Result<Vec<GpioWrite>> {
    ensure!(
        stores.len() == writes.len(),
        "plugin saw {} GPIO stores but the trace has {} pl061_write events \
         (is every written PL061 block watched?)",
        stores.len(),
        writes.len()
    );
    let mut devices: HashMap<&str, u32> = HashMap::new();
    let mut out = Vec::with_capacity(stores.len());
    for (i, (&(count, addr), w)) in stores.iter().zip(writes).enumerate() {
        ensure!(
            addr & 0xfff == w.offset,
            "write #{i}: plugin store at {addr:#x} (count {count}) but trace offset {:#x}",
            w.offset
        );
        let block = addr & !0xfff;
        if !w.device.is_empty() {
            let b = *devices.entry(&w.device).or_insert(block);
            ensure!(
                b == block,
                "write #{i}: trace device {} seen at {b:#x} and {block:#x}",
                w.device
            );
        }
        out.push(GpioWrite {
            count,
            addr,
            value: w.value,
        });
    }
    Ok(out)
}

/// Replays the writes to the PL061 at `port` like QEMU does and returns (time ns, data & dir) after
/// each write that changed the pins; time = count << shift.
pub fn replay_port(writes: &[GpioWrite], port: u32, shift: u32) -> Vec<(u64, u8)> {
    let (mut data, mut dir, mut pins) = (0u8, 0u8, 0u8);
    let mut out = Vec::new();
    for w in writes.iter().filter(|w| w.addr & !0xfff == port) {
        let off = w.addr & 0xfff;
        if off < 0x400 {
            let mask = (off >> 2) as u8 & dir;
            data = (data & !mask) | (w.value as u8 & mask);
        } else if off == 0x400 {
            dir = w.value as u8;
        }
        if data & dir != pins {
            pins = data & dir;
            out.push((w.count << shift, pins));
        }
    }
    out
}

/// The QEMU command line of a capture (without working directory or stdio settings).
pub fn qemu_command(
    spec: &CaptureSpec,
    elf: &Path,
    plugin: &Path,
    log: &Path,
    trace: &Path,
) -> Command {
    let mut plugin_arg = format!("{},out={}", plugin.display(), log.display());
    for p in &spec.gpio_ports {
        plugin_arg += &format!(",gpio={p:#x}");
    }
    for (k, h) in spec.handlers.iter().enumerate() {
        plugin_arg += &format!(",h{k}_entry={:#x}", h.entry);
        for e in &h.exits {
            plugin_arg += &format!(",h{k}_exit={e:#x}");
        }
    }
    if let Some((k, over)) = spec.trace {
        plugin_arg += &format!(",trace={k},over={over}");
    }
    let mut cmd = Command::new("qemu-system-arm");
    match spec.machine {
        Machine::Lm3s6965 => cmd
            .args(["-cpu", "cortex-m3", "-machine", "lm3s6965evb", "-nographic"])
            .args(["-semihosting-config", "enable=on,target=native"]),
        Machine::Netduinoplus2 => cmd.args(["-machine", "netduinoplus2", "-nographic"]),
    };
    cmd.arg("-icount")
        .arg(format!("shift={},sleep=off", spec.icount_shift))
        .arg("-kernel")
        .arg(elf);
    match spec.machine {
        Machine::Lm3s6965 => cmd.args(["-trace", "pl061_write", "-D"]),
        Machine::Netduinoplus2 => cmd.args(["-d", "unimp", "-D"]),
    };
    cmd.arg(trace)
        .arg("-plugin")
        .arg(plugin_arg)
        .args(&spec.extra_args);
    cmd
}

/// First line of `qemu-system-arm --version`, e.g. `QEMU emulator version 7.2.x (Debian ...)`.
pub fn qemu_version() -> Result<String> {
    let out = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .context("running qemu-system-arm --version")?;
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .unwrap_or("")
        .to_string())
}

fn reader(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        buf
    })
}

/// `: the disk is full (N bytes free on the file system of DIR)` when the file system holding
/// `dir` has (next to) no room left, else empty: why a log QEMU wrote may be incomplete.
pub fn full_disk(dir: &Path) -> String {
    let Ok(c) = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes()) else {
        return String::new();
    };
    // SAFETY: statvfs(3) reads the NUL-terminated path and fills the struct we own.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
        return String::new();
    }
    let free = st.f_bavail as u64 * st.f_frsize as u64;
    if free < 64 * 1024 {
        format!(
            ": the disk is full ({free} bytes free on the file system of {})",
            dir.display()
        )
    } else {
        String::new()
    }
}

/// Runs the firmware under QEMU and returns the capture. The firmware's own exit status is returned
/// in [`Capture::status`]; errors are for QEMU failing to run, the timeout, or inconsistent logs.
pub fn run_capture(spec: &CaptureSpec) -> Result<Capture> {
    ensure!(spec.handlers.len() <= 16, "at most 16 handlers");
    if let Some((k, _)) = spec.trace {
        ensure!(
            k < spec.handlers.len(),
            "traced handler {k}: no such handler"
        );
    }
    crate::emulator::tools::ensure_tool("qemu-system-arm")?;
    let elf = std::fs::canonicalize(&spec.elf)
        .with_context(|| format!("firmware ELF {}", spec.elf.display()))?;
    let run_dir = std::fs::canonicalize(&spec.run_dir)
        .with_context(|| format!("run directory {}", spec.run_dir.display()))?;
    let dir = run_dir.join(CAPTURE_DIR);
    let plugin = crate::emulator::plugin::write_plugin(&dir)?;
    let log = dir.join("plugin.log");
    let trace = dir.join("trace.log");
    // The firmware's log decoder (its ELF's defmt table), and no stale result file: a firmware that
    // ends before it writes one leaves none.
    let fw_log = crate::emulator::defmtlog::Log::from_elf(
        &std::fs::read(&elf).with_context(|| format!("reading {}", elf.display()))?,
    )?;
    let result = run_dir.join(crate::lm3s_files::RESULT_NAME);
    for f in [&log, &trace, &result] {
        if f.exists() {
            std::fs::remove_file(f).with_context(|| format!("removing {}", f.display()))?;
        }
    }
    let mut cmd = qemu_command(spec, &elf, &plugin, &log, &trace);
    // QEMU never outlives the thread that started it (a killed `serve`, a test that panics and
    // ends its process): the kernel sends it SIGKILL when its parent goes.
    // SAFETY: prctl(2) between fork and exec is async-signal-safe and touches no memory of ours.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut cmd, || {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
    let mut child = cmd
        .current_dir(&run_dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting qemu-system-arm")?;
    let out = reader(child.stdout.take().context("stdout")?);
    let err = reader(child.stderr.take().context("stderr")?);
    let start = Instant::now();
    let mut stopping = false;
    let status = loop {
        if let Some(s) = child.try_wait()? {
            break s;
        }
        if let Some(stop) = &spec.stop {
            if !stopping && stop.load(std::sync::atomic::Ordering::SeqCst) {
                stopping = true;
                // SAFETY: kill(2) with the child's pid and SIGTERM: no memory is touched.
                unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
            }
        }
        if spec.timeout != Duration::MAX && start.elapsed() > spec.timeout {
            let _ = child.kill();
            let _ = child.wait();
            let stdout = fw_log.decode(&out.join().unwrap_or_default());
            bail!(
                "QEMU timed out after {:?} (killed); firmware output so far:\n{stdout}",
                spec.timeout
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let stdout = fw_log.decode(&out.join().unwrap_or_default());
    let stderr = String::from_utf8_lossy(&err.join().unwrap_or_default()).into_owned();
    let result = std::fs::read_to_string(&result).unwrap_or_default();
    let fail = |what: String| {
        anyhow::anyhow!(
            "{what}; QEMU {status} (the millac plugin supports QEMU 7.x, found {}), stderr:\n{stderr}",
            qemu_version().unwrap_or_else(|e| e.to_string())
        )
    };
    // A log QEMU or the plugin could not write whole (a full disk): said as such, with the file.
    if let Some(why) = stderr
        .lines()
        .find_map(|l| l.strip_prefix("millac_plugin: cannot write "))
    {
        bail!(
            "could not write the capture's plugin log {why}{}",
            full_disk(&dir)
        );
    }
    let log_text = std::fs::read_to_string(&log)
        .map_err(|e| fail(format!("no plugin log {}: {e}", log.display())))?;
    let plog = parse_plugin_log(&log_text)
        .with_context(|| format!("{}{}", log.display(), full_disk(&dir)))?;
    let total = plog
        .total
        .ok_or_else(|| fail("plugin log has no final line (atexit did not run)".into()))?;
    let trace_text = std::fs::read_to_string(&trace).unwrap_or_default();
    if !trace_text.is_empty() && !trace_text.ends_with('\n') {
        bail!(
            "QEMU's trace log {} was cut short{}",
            trace.display(),
            full_disk(&dir)
        );
    }
    let pins = match spec.machine {
        Machine::Lm3s6965 => parse_trace(&trace_text)
            .and_then(|t| zip_writes(&plog.stores, &t))
            .map(|w| replay_port(&w, spec.pin_port, spec.icount_shift)),
        Machine::Netduinoplus2 => parse_unimp_gpio(&trace_text)
            .and_then(|t| zip_f4_writes(&plog.stores, &t, &spec.gpio_ports))
            .map(|w| replay_bsrr(&w, spec.pin_port, F4_FIRST_PIN, spec.icount_shift)),
    };
    let pins = pins.map_err(|e| {
        let full = full_disk(&dir);
        if full.is_empty() {
            e
        } else {
            e.context(format!(
                "QEMU's logs in {} are incomplete{full}",
                dir.display()
            ))
        }
    })?;
    let mut handlers: Vec<(String, Vec<u64>)> = spec
        .handlers
        .iter()
        .map(|h| (h.name.clone(), Vec::new()))
        .collect();
    let mut handler_starts = vec![Vec::new(); handlers.len()];
    for &(k, n, c) in &plog.handlers {
        handlers
            .get_mut(k)
            .with_context(|| format!("plugin reported unknown handler {k}"))?
            .1
            .push(n);
        handler_starts[k].push(c << spec.icount_shift);
    }
    // The two logs are parsed whole (the pins, the handlers' counts and traces are in the capture
    // now): removed, so a run leaves only its outputs (the demo's are 300 MB; a log kept on an
    // error above is there to be read).
    for f in [&log, &trace] {
        let _ = std::fs::remove_file(f);
    }
    let traces = plog
        .traces
        .into_iter()
        .map(|(handler, c, pcs)| HandlerTrace {
            handler,
            start_ns: c << spec.icount_shift,
            pcs,
        })
        .collect();
    Ok(Capture {
        pins,
        handlers,
        handler_starts,
        traces,
        total_instructions: total,
        end_ns: total << spec.icount_shift,
        stdout,
        result,
        stderr,
        status: status.code(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_trace_lines() {
        let t = "pl061_write /machine/unattached/device[9] offset 0x400 value 0x3f\n\
                 other line\n\
                 1234@1700000000.000001:pl061_write offset 0x4 value 0x1\n";
        let w = parse_trace(t).unwrap();
        assert_eq!(
            w,
            vec![
                TraceWrite {
                    device: "/machine/unattached/device[9]".into(),
                    offset: 0x400,
                    value: 0x3f
                },
                TraceWrite {
                    device: String::new(),
                    offset: 4,
                    value: 1
                },
            ]
        );
        assert!(parse_trace("pl061_write offset zz value 0x1").is_err());
    }

    #[test]
    fn parses_plugin_log() {
        let l = parse_plugin_log("s 36 40005400\nh 0 13 20\nt 0 20 4c 4e\ne 1e9c9\n").unwrap();
        assert_eq!(l.stores, vec![(0x36, 0x4000_5400)]);
        assert_eq!(l.handlers, vec![(0, 0x13, 0x20)]);
        assert_eq!(l.traces, vec![(0, 0x20, vec![0x4c, 0x4e])]);
        assert_eq!(l.total, Some(0x1e9c9));
        assert!(parse_plugin_log("x 1\n").is_err());
        assert!(parse_plugin_log("h 0 13\n").is_err());
        assert!(parse_plugin_log("t 0 20 zz\n").is_err());
    }

    fn tw(dev: &str, offset: u32, value: u32) -> TraceWrite {
        TraceWrite {
            device: dev.into(),
            offset,
            value,
        }
    }

    #[test]
    fn zip_and_replay() {
        let stores = [
            (10, 0x4000_5400), // DIR = 0x3f
            (20, 0x4000_4400), // port A DIR (ignored for port B)
            (30, 0x4000_5004), // PB0 := 1
            (40, 0x4000_5020), // PB3 := 1
            (50, 0x4000_53fc), // all := 0x09 (no change)
            (60, 0x4000_5004), // PB0 := 0
            (70, 0x4000_5200), // PB7 (input, dir 0): ignored
        ];
        let writes = [
            tw("b", 0x400, 0x3f),
            tw("a", 0x400, 0xff),
            tw("b", 0x004, 0x01),
            tw("b", 0x020, 0xff),
            tw("b", 0x3fc, 0x09),
            tw("b", 0x004, 0x00),
            tw("b", 0x200, 0x80),
        ];
        let z = zip_writes(&stores, &writes).unwrap();
        assert_eq!(
            replay_port(&z, PORT_B, 4),
            vec![(480, 0x01), (640, 0x09), (960, 0x08)]
        );
    }

    #[test]
    fn f4_unimp_writes_replay_through_bsrr() {
        let log = "I2S2ext: unimplemented device write (size 4, offset 0x000, value 0x0000aaaa)\n\
                   GPIOC: unimplemented device read  (size 4, offset 0x014)\n\
                   GPIOC: unimplemented device write (size 4, offset 0x018, value 0x03f00000)\n\
                   GPIOC: unimplemented device write (size 4, offset 0x018, value 0x00600010)\n\
                   GPIOD: unimplemented device write (size 4, offset 0x018, value 0x00000001)\n\
                   GPIOA: unimplemented device write (size 4, offset 0x000, value 0x000000a0)\n\
                   GPIOC: unimplemented device write (size 4, offset 0x018, value 0x03900200)\n";
        let w = parse_unimp_gpio(log).unwrap();
        assert_eq!(w.len(), 5);
        assert_eq!(f4_gpio_address(&w[0]), Some(0x4002_0818));
        assert_eq!(f4_gpio_address(&w[2]), Some(0x4002_0C18));
        let stores = [
            (10, 0x4002_0818),
            (20, 0x4002_0818),
            (25, 0x4002_0C18),
            (30, 0x4002_0818),
        ];
        let z = zip_f4_writes(&stores, &w, &[F4_GPIOC]).unwrap();
        assert_eq!(z.len(), 4);
        // PC4 up (X PULSE), then X PULSE down and PC9 up (Z SIGN); GPIOD is not port C.
        assert_eq!(
            replay_bsrr(&z, F4_GPIOC, F4_FIRST_PIN, 4),
            vec![(320, 0b00_0001), (480, 0b10_0000)]
        );
        assert!(zip_f4_writes(&stores[..3], &w, &[F4_GPIOC]).is_err());
        assert!(parse_unimp_gpio("GPIOC: unimplemented device write (size 4, offset zz)").is_err());
    }

    #[test]
    fn zip_fails_loudly() {
        let stores = [(1, 0x4000_5004)];
        assert!(zip_writes(&stores, &[]).is_err());
        assert!(zip_writes(&stores, &[tw("b", 0x8, 1)]).is_err());
        let two = [(1, 0x4000_5004), (2, 0x4000_4004)];
        assert!(zip_writes(&two, &[tw("b", 4, 1), tw("b", 4, 1)]).is_err());
    }
}
