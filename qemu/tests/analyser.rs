//! Integration tests of the virtual logic analyser (host): the embedded QEMU plugin, a capture of a
//! hand-assembled Cortex-M3 image under QEMU, ELF symbol lookup, and sigrok's stepper_motor decode.
//! They need qemu-system-arm and sigrok-cli: installed as root, else the tests fail saying what to
//! install (never skipped).
use millac_qemu::emulator::capture::{run_capture, CaptureSpec, HandlerSpec};
use millac_qemu::{analysis::sigrok, analysis::vcd, emulator::elf, emulator::plugin};
use object::{Object, ObjectSymbol};
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn plugin_is_a_v1_qemu_plugin() {
    // include_bytes! data is only byte-aligned; the ELF parser wants an aligned copy.
    let data = plugin::PLUGIN_SO.to_vec();
    let f = object::File::parse(&*data).unwrap();
    let names: Vec<String> = f
        .dynamic_symbols()
        .filter(|s| !s.is_undefined())
        .filter_map(|s| s.name().ok().map(str::to_string))
        .collect();
    assert!(
        names.iter().any(|n| n == "qemu_plugin_install"),
        "{names:?}"
    );
    assert!(
        names.iter().any(|n| n == "qemu_plugin_version"),
        "{names:?}"
    );
}

/// A raw Cortex-M3 image: vector table, then GPIOB DIR/DEN = 0x3f, masked data writes, and a
/// semihosting SYS_EXIT (status 0). Instruction k (1-based) executes at count k.
fn test_image() -> Vec<u8> {
    let mut img = Vec::new();
    img.extend_from_slice(&0x2000_1000u32.to_le_bytes()); // initial SP
    img.extend_from_slice(&0x41u32.to_le_bytes()); // reset vector -> 0x40 (Thumb)
    img.resize(0x40, 0);
    let code: [u16; 20] = [
        0x4809, // 0x40 ldr r0, [pc, #36] ; =0x40005000
        0x213F, // 0x42 movs r1, #0x3f
        0xF8C0, 0x1400, // 0x44 str.w r1, [r0, #0x400]  DIR
        0xF8C0, 0x151C, // 0x48 str.w r1, [r0, #0x51c]  DEN
        0x2101, // 0x4c movs r1, #1          <- "handler" entry
        0x6041, // 0x4e str r1, [r0, #4]     PB0 := 1
        0x2108, // 0x50 movs r1, #8
        0x6201, // 0x52 str r1, [r0, #0x20]  PB3 := 1
        0x2100, // 0x54 movs r1, #0
        0x6041, // 0x56 str r1, [r0, #4]     PB0 := 0
        0x213F, // 0x58 movs r1, #0x3f
        0xF8C0, 0x13FC, // 0x5a str.w r1, [r0, #0x3fc]  all := 0x3f
        0x6842, // 0x5e ldr r2, [r0, #4]     a GPIO load: not a write  <- "handler" exit
        0x2018, // 0x60 movs r0, #0x18 (SYS_EXIT)
        0x4902, // 0x62 ldr r1, [pc, #8] ; =0x20026 (ADP_Stopped_ApplicationExit)
        0xBEAB, // 0x64 bkpt 0xab
        0xE7FE, // 0x66 b .
    ];
    for h in code {
        img.extend_from_slice(&h.to_le_bytes());
    }
    img.extend_from_slice(&0x4000_5000u32.to_le_bytes()); // 0x68
    img.extend_from_slice(&0x0002_0026u32.to_le_bytes()); // 0x6c
    img
}

#[test]
fn capture_of_a_hand_assembled_image() {
    let dir = scratch("capture");
    let image = dir.join("image.bin");
    std::fs::write(&image, test_image()).unwrap();
    let mut spec = CaptureSpec::new(&image, &dir);
    spec.icount_shift = 3;
    spec.timeout = std::time::Duration::from_secs(60);
    spec.handlers.push(HandlerSpec {
        name: "block".into(),
        entry: 0x4c,
        exits: vec![0x5e],
    });
    let c = run_capture(&spec).unwrap();
    assert_eq!(c.status, Some(0), "stderr: {}", c.stderr);
    assert_eq!(
        c.pins,
        vec![
            (6 << 3, 0x01),
            (8 << 3, 0x09),
            (10 << 3, 0x08),
            (12 << 3, 0x3f)
        ]
    );
    assert_eq!(c.handlers, vec![("block".to_string(), vec![9])]);
    // The "handler" starts at instruction 5.
    assert_eq!(c.handler_starts, vec![vec![5 << 3]]);
    assert!(c.traces.is_empty());
    assert_eq!(c.total_instructions, 16);
    assert_eq!(c.end_ns, 16 << 3);
    // QEMU's two logs, parsed whole, are not left behind (a long job's are hundreds of MB).
    let logs = dir.join(millac_qemu::emulator::capture::CAPTURE_DIR);
    for log in ["plugin.log", "trace.log"] {
        assert!(!logs.join(log).exists(), "{log} left in {}", logs.display());
    }
    // Deterministic: a second run gives the same capture.
    assert_eq!(run_capture(&spec).unwrap(), c);
    // A traced run: the same counts, and the PCs of the calls longer than 8 instructions, entry
    // to return (the four-byte store.w at 0x5a is one instruction).
    let mut traced = spec.clone();
    traced.trace = Some((0, 8));
    let t = run_capture(&traced).unwrap();
    assert_eq!((&t.pins, &t.handlers), (&c.pins, &c.handlers));
    assert_eq!(t.traces.len(), 1);
    assert_eq!(t.traces[0].start_ns, 5 << 3);
    assert_eq!(
        t.traces[0].pcs,
        vec![0x4c, 0x4e, 0x50, 0x52, 0x54, 0x56, 0x58, 0x5a, 0x5e]
    );
    traced.trace = Some((0, 9));
    assert!(run_capture(&traced).unwrap().traces.is_empty());
    // QEMU failing to start is an error that carries QEMU's stderr.
    spec.extra_args.push("-no-such-option".into());
    let e = format!("{:#}", run_capture(&spec).unwrap_err());
    assert!(e.contains("no-such-option"), "{e}");
}

#[test]
fn finds_function_and_returns_in_an_elf() {
    use object::write::{Object as WObject, Symbol, SymbolSection};
    use object::{Architecture, BinaryFormat, Endianness, SymbolFlags, SymbolKind, SymbolScope};
    let mut obj = WObject::new(BinaryFormat::Elf, Architecture::Arm, Endianness::Little);
    let text = obj.add_section(Vec::new(), b".text".to_vec(), object::SectionKind::Text);
    // padding, then push {r7, lr}; bx lr; pop.w {r4-r11, pc}; pop {r7, pc}
    let code: Vec<u8> = [0xBF00u16, 0xBF00, 0xB580, 0x4770, 0xE8BD, 0x8FF0, 0xBD80]
        .iter()
        .flat_map(|h| h.to_le_bytes())
        .collect();
    obj.append_section_data(text, &code, 4);
    obj.add_symbol(Symbol {
        name: b"TIMER_0A".to_vec(),
        value: 4 | 1, // Thumb bit set, as in firmware ELF files
        size: 10,
        kind: SymbolKind::Text,
        scope: SymbolScope::Linkage,
        weak: false,
        section: SymbolSection::Section(text),
        flags: SymbolFlags::None,
    });
    let bytes = obj.write().unwrap();
    let f = elf::find_function_in(&bytes, "TIMER_0A").unwrap();
    assert_eq!((f.addr, f.size), (4, 10));
    assert_eq!(f.returns, vec![6, 8, 12]);
    assert!(elf::find_function_in(&bytes, "TIMER_1A").is_err());
}

#[test]
fn sigrok_decodes_known_positions() {
    // X: 3 steps +, then 1 step -  => +2. Y: 2 steps -  => -2. Z: none => 0.
    let mut ev = Vec::new();
    let mut t = 1_000;
    let mut pins = 0x08u8; // X_SIGN high
    let mut push = |pins: u8, t: &mut u64| {
        ev.push((*t, pins));
        *t += 1_000;
    };
    for _ in 0..3 {
        pins |= 0x01 | 0x02;
        push(pins, &mut t);
        pins &= !0x03;
        push(pins, &mut t);
    }
    pins &= !0x08; // X_SIGN low
    push(pins, &mut t);
    pins |= 0x01;
    push(pins, &mut t);
    pins &= !0x01;
    push(pins, &mut t);
    assert_eq!(vcd::positions(0x08, &ev), [2, -3, 0]);
    let dir = scratch("sigrok");
    let path = dir.join("known.vcd");
    vcd::write_vcd(&path, 0x08, &ev, Some(t)).unwrap();
    assert_eq!(sigrok::decode_positions(&path).unwrap(), [2, -3, 0]);
    // A foreign-looking VCD (other timescale and scope, extra wire) decodes the same.
    let foreign = std::fs::read_to_string(&path)
        .unwrap()
        .replace("$timescale 1 ns $end", "$timescale 100 ps $end")
        .replace("module millac", "module libsigrok")
        .replace("$upscope", "$var wire 1 ( CLK $end\n$upscope")
        .lines()
        .map(|l| match l.strip_prefix('#') {
            Some(n) => format!("#{}", n.parse::<u64>().unwrap() * 10),
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    let fpath = dir.join("foreign.vcd");
    std::fs::write(&fpath, foreign).unwrap();
    assert_eq!(
        vcd::read_vcd(&std::fs::read_to_string(&fpath).unwrap())
            .unwrap()
            .events,
        ev
    );
    assert_eq!(sigrok::decode_positions(&fpath).unwrap(), [2, -3, 0]);
}

/// Pin events of the host core's frames for `program`, as the firmware drives the pins: the SIGN
/// lines 1 us before a frame's pulses, PULSE lines high together (the Y and Z edges `skew_ns`
/// after X's, as a real board or analyser may show them), low 5 us later. Also returns the
/// largest distance of a frame's end position from its block's ideal line (lines only).
fn host_frames(program: &str, skew_ns: u64) -> (Vec<(u64, u8)>, f64) {
    use millac::nc::{sim::Sim, Frame, FrameConfig};
    use millac_qemu::{analysis, host::acsim};
    let settings = millac::Settings::default();
    let prog = analysis::load_program(program, &settings).unwrap();
    let mut frame = Frame::new(FrameConfig::from_settings(&settings));
    let (mut t, mut signs, mut ev, mut dev) = (100_000u64, 0u8, Vec::new(), 0.0f64);
    for f in Sim::new(&mut frame, prog.iter().map(|b| b.block), u32::MAX, u64::MAX) {
        t += acsim::period_ns(&settings, f.rate);
        let p = f.pulses;
        if p.steps == 0 {
            continue;
        }
        signs = (signs & !(p.steps << 3)) | ((p.signs & p.steps) << 3);
        ev.push((t - 1_000, signs));
        let mut pins = signs;
        for k in 0..3 {
            if p.steps & (1 << k) != 0 {
                pins |= 1 << k;
                ev.push((t + if k == 0 { 0 } else { skew_ns }, pins));
            }
        }
        ev.push((t + 5_000 + skew_ns, signs));
        let b = &prog[f.block as usize];
        let (s, e) = (b.start.map(f64::from), b.end.map(f64::from));
        let d: Vec<f64> = (0..3).map(|k| e[k] - s[k]).collect();
        let v: Vec<f64> = (0..3).map(|k| f64::from(f.position[k]) - s[k]).collect();
        let l2: f64 = d.iter().map(|x| x * x).sum();
        let u = (v.iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() / l2).clamp(0.0, 1.0);
        let r2: f64 = (0..3).map(|k| (v[k] - u * d[k]).powi(2)).sum();
        dev = dev.max(r2.sqrt());
    }
    ev.sort_by_key(|e| e.0);
    (ev, dev)
}

#[test]
fn deviation_is_scored_per_frame_not_per_edge() {
    use millac_qemu::analysis;
    let program = "G1 X0.05 F10\nG1 X0 Y0.03\n";
    let settings = millac::Settings::default();
    let prog = analysis::load_program(program, &settings).unwrap();
    for skew_ns in [0, 200] {
        let (ev, host_dev) = host_frames(program, skew_ns);
        let r = analysis::analyse(&prog, &settings, 0, &ev);
        assert!(r.counts_match && r.blocks.iter().all(|b| b.end_exact));
        assert!(
            r.max_deviation_blu < 1.0,
            "skew {skew_ns} ns: {} BLU",
            r.max_deviation_blu
        );
        assert!(
            (r.max_deviation_blu - host_dev).abs() < 1e-9,
            "skew {skew_ns} ns: capture {} BLU, host core per frame {host_dev} BLU",
            r.max_deviation_blu
        );
    }
}

/// A capture of a real run, exported by sigrok-cli itself (downsampled to 10 MHz, as from a logic
/// analyser: sigrok writes a `META` line, `$date`, `$version` and a `$comment` before the
/// definitions and the values on the timestamp lines), analyses like the original: same final
/// position, exact end points, same per-frame path and deviation, pulses equal to the host core's.
#[test]
fn sigrok_exported_capture_analyses_like_the_original() {
    use millac_qemu::{analysis, emulator::runner, emulator::tools};
    let program = "G1 X0.05 F10\nG1 X0 Y0.03\n";
    let dir = scratch("sigrok-export");
    let o = runner::run(program, &dir, 4).expect("run");
    assert!(o.ok, "{:#}", o.summary);
    tools::ensure_tool("sigrok-cli").unwrap();
    let original = dir.join("capture.vcd");
    let export = dir.join("export.vcd");
    let st = std::process::Command::new("sigrok-cli")
        .arg("-i")
        .arg(&original)
        .args(["-I", "vcd:downsample=100", "-O", "vcd", "-o"])
        .arg(&export)
        .status()
        .unwrap();
    assert!(st.success());
    let settings = millac::Settings::default();
    let prog = analysis::load_program(program, &settings).unwrap();
    let read = |p: &std::path::Path| vcd::read_vcd(&std::fs::read_to_string(p).unwrap()).unwrap();
    let (a, b) = (read(&original), read(&export));
    let ra = analysis::analyse(&prog, &settings, a.initial, &a.events);
    let rb = analysis::analyse(&prog, &settings, b.initial, &b.events);
    assert!(rb.counts_match && rb.blocks.iter().all(|x| x.end_exact));
    assert_eq!(rb.final_position, ra.final_position);
    assert_eq!(rb.max_deviation_blu, ra.max_deviation_blu);
    let path = |t: &vcd::PinTrace| {
        let e = analysis::edges(t.initial, &t.events);
        let f = analysis::frame_of_edges(&e.edges, analysis::frame_window_ns(&settings));
        e.edges
            .iter()
            .zip(f)
            .map(|(x, f)| (f, x.axis, x.dir))
            .collect::<Vec<_>>()
    };
    assert_eq!(path(&b), path(&a));
    let groups = analysis::edges(b.initial, &b.events).groups;
    assert_eq!(analysis::compare_with_host(&prog, &settings, &groups), None);
    // The command line reads it too.
    let prog_file = dir.join("program.nc");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .arg("analyse")
        .arg(&export)
        .arg(&prog_file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let fp = &s["final_position_blu"];
    assert_eq!(
        [&fp["x"], &fp["y"], &fp["z"]].map(|v| v.as_i64().unwrap()),
        ra.final_position
    );
    assert_eq!(s["end_points_exact"], true);
}
