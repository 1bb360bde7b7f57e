//! Checks of the Nucleo-F446RE firmware that need no board (host, CI): it builds in release, it
//! fits the flash and RAM budgets recorded in hal/nucleo-f446re/budget.txt, and its frame ISR
//! (TIM2) and pulse-end ISR (TIM5) contain no call and no panic path, as on the QEMU board. Its
//! `qemu` build runs under QEMU's netduinoplus2: a program streamed over USART2 with the grbl
//! protocol gets its `ok`s, ends `Idle` at the right MPos, and the GPIOC BSRR stores carry exactly
//! the host core's pulses; the frame's worst case (a line that decelerates into the next one) runs
//! within the board's stated instruction bound.
use millac::protocol::table::MachineSettings;
use millac_qemu::emulator::firmware::{
    build_board, build_board_in, linker_of, workspace, NUCLEO_F446RE, NUCLEO_F446RE_QEMU,
};
use millac_qemu::{analysis, analysis::vcd, emulator::elf, emulator::f446, emulator::tools};
use std::path::Path;
use std::time::{Duration, Instant};

// The budget benchmarks' programs (only `CORNERS` here).
#[allow(dead_code)]
#[path = "../examples/common/programs.rs"]
mod programs;

/// The layout of an F446 image: linked with the board's own memory map and by flip-link.
fn assert_board_layout(elf: &Path) {
    // The board's own memory map (hal/nucleo-f446re/memory.x): the vector table at the start of
    // the F446's flash, where probe-rs flashes it (a memory.x in the linker's working directory,
    // the workspace root, used to win: the LM3S map, flash at 0).
    use object::{Object, ObjectSection};
    let data = std::fs::read(elf).unwrap();
    let file = object::File::parse(&*data).unwrap();
    let vt = file.section_by_name(".vector_table").unwrap();
    assert_eq!(vt.address(), 0x0800_0000, "vector table address");
    // flip-link puts the statics at the top of RAM (the stack below them): they end at the end
    // of the F446's 128 KiB, short of it by less than 8 bytes: flip-link moves them by a multiple
    // of 8 (the stack pointer's alignment under the AAPCS, and at least the sections' own), so a
    // size that is not a multiple of 8 leaves a gap (4 bytes when issue 10 added a status word).
    let ram_sections: Vec<_> = file
        .sections()
        .filter(|s| s.address() >= 0x2000_0000 && s.size() > 0)
        .collect();
    let top = ram_sections
        .iter()
        .map(|s| s.address() + s.size())
        .max()
        .unwrap();
    let align = ram_sections.iter().map(|s| s.align()).max().unwrap();
    let end = 0x2000_0000 + 128 * 1024;
    assert!(
        top <= end && end - top < align.max(8),
        "end of the statics {top:#x}, RAM ends at {end:#x}, alignment {align}"
    );
}

/// The fresh machine: on a toolchain without flip-link (an empty cargo install root, PATH not
/// looked at) the set-up `build_board` runs installs it, and the firmware links with that copy
/// (flip-link's layout is there). The install builds in target/cargo-install, as `build_board`'s
/// does, so only the first run builds flip-link; the firmware's ELF is removed first, so every
/// run links it.
#[test]
fn f446_links_with_the_flip_link_installed_on_a_toolchain_without_it() {
    let ws = workspace();
    let root = ws.join("target").join("fresh-toolchain");
    let _ = std::fs::remove_dir_all(&root);
    let tool = linker_of(NUCLEO_F446RE.target).expect("the F446 links with a wrapper");
    assert!(!root.join("bin").join(tool.program).exists());
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let linker = tools::ensure_cargo_tool_in(
        tool,
        Path::new(&cargo),
        &root,
        &ws.join("target").join("cargo-install"),
        &ws,
    )
    .unwrap();
    assert_eq!(linker, root.join("bin").join(tool.program));
    assert!(linker.is_file());

    let target_dir = ws.join("target").join("firmware-fresh-toolchain");
    let release = target_dir.join(NUCLEO_F446RE.target).join("release");
    let _ = std::fs::remove_file(release.join(NUCLEO_F446RE.bin));
    let stem = NUCLEO_F446RE.bin.replace('-', "_");
    for entry in std::fs::read_dir(release.join("deps"))
        .into_iter()
        .flatten()
    {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with(&format!("{stem}-")) && path.extension().is_none() {
            std::fs::remove_file(&path).unwrap();
        }
    }
    let elf = build_board_in(&NUCLEO_F446RE, &target_dir, Some(&linker)).unwrap();
    assert_board_layout(&elf);
}

#[test]
fn f446_interrupts_have_no_calls_and_no_panic_path() {
    let elf = build_board(&NUCLEO_F446RE).unwrap();
    for name in ["TIM2", "TIM5"] {
        let f = elf::find_function(&elf, name).unwrap();
        assert!(f.size > 40, "{name}: {} bytes", f.size);
        assert!(
            f.calls_and_traps.is_empty(),
            "{name} calls or traps at {:x?}",
            f.calls_and_traps
        );
    }
    // The scan sees calls where there are some: init calls the HAL and defmt.
    let init = elf::find_function(&elf, "main").unwrap();
    assert!(!init.calls_and_traps.is_empty());
}

#[test]
fn f446_fits_its_flash_and_ram_budgets() {
    let elf = build_board(&NUCLEO_F446RE).unwrap();
    assert_board_layout(&elf);
    NUCLEO_F446RE.check_budgets(&elf).unwrap();
}

#[test]
fn f446_under_qemu_streams_grbl_and_pulses_like_the_host_core() {
    let elf = build_board(&NUCLEO_F446RE_QEMU).unwrap();
    // Lines, a rapid with Z, an arc, and back: every axis both ways.
    let program = "G20 G90\nG1 X0.02 Y0.01 F30\nG0 X0.03 Y-0.01 Z0.005\n\
                   G2 X0.01 Y0.01 I-0.01 J0.01 F30\nG1 X0.004 Y0.002 Z-0.002 F20\n";
    let dir = workspace().join("target").join("f446-qemu-stream");
    let t0 = Instant::now();
    let s = f446::stream(
        &elf,
        &dir,
        program,
        4,
        &["TIM2", "TIM5"],
        Duration::from_secs(60),
    )
    .unwrap();
    println!("wall time {:?}, status {}", t0.elapsed(), s.status);
    assert!(
        s.banner.iter().any(|l| l.starts_with("Grbl 1.1")),
        "{:?}",
        s.banner
    );
    assert_eq!(s.answers.len(), 5);
    for (line, got) in &s.answers {
        assert_eq!(
            got.last().map(String::as_str),
            Some("ok"),
            "{line}: {got:?}"
        );
    }

    // The pins against the host core: every block its pulses, the frames' pulse groups equal.
    let settings = MachineSettings::default().nc;
    let prog = analysis::load_program(program, &settings).unwrap();
    let report = analysis::analyse(&prog, &settings, 0, &s.capture.pins);
    assert!(report.counts_match, "pulse counts per block differ");
    assert!(report.end_points_exact(), "{:?}", report.blocks);
    let edges = analysis::edges(0, &s.capture.pins);
    assert_eq!(
        analysis::compare_with_host(&prog, &settings, &edges.groups),
        None,
        "the pulse groups differ from the host core's"
    );
    let end = vcd::positions(0, &s.capture.pins);
    assert_eq!(end, [40, 20, -20]);
    let rises: Vec<usize> = (0..3)
        .map(|k| edges.edges.iter().filter(|e| e.axis == k).count())
        .collect();
    println!("rising edges per axis {rises:?}, end {end:?} BLU");
    assert!(rises.iter().all(|&n| n > 0));

    // The status report: idle at the pins' end point (mm, 0.0001 in per BLU).
    assert!(s.status.starts_with("<Idle"), "{}", s.status);
    let mpos = f446::mpos(&s.status).unwrap();
    for k in 0..3 {
        let want = end[k] as f64 * 0.00254;
        assert!(
            (mpos[k] - want).abs() < 0.0006,
            "MPos {mpos:?}, pins {end:?}"
        );
    }

    // Both ISRs ran under the plugin within the instruction bounds the board's stated times
    // (`f446_facts::LIMITS`) are derived from: a frame that grows past them must come
    // with new limits.
    let bounds = millac_qemu::f446_facts::ISR_BOUNDS;
    let (frames, pulses) = (&s.capture.handlers[0].1, &s.capture.handlers[1].1);
    assert!(frames.len() > 100 && !pulses.is_empty());
    let (fmax, pmax) = (frames.iter().max().unwrap(), pulses.iter().max().unwrap());
    assert!(
        *fmax <= u64::from(bounds.frame_instructions),
        "frame ISR {fmax}"
    );
    assert!(
        *pmax <= u64::from(bounds.pulse_end_instructions),
        "pulse-end ISR {pmax}"
    );
    println!(
        "TIM2 max {} instructions over {} frames, TIM5 max {} over {}",
        frames.iter().max().unwrap(),
        frames.len(),
        pulses.iter().max().unwrap(),
        pulses.len()
    );
}

/// The frame's worst case under CI, whatever the host's load: the corner program (lines that
/// decelerate into the next line, all three axes in each line's last command: the frame that
/// ends one line and chains the next) is queued under a hold before it runs, as the budget
/// benchmark does. Nothing moved while it was sent; it ends where it started with the host
/// core's pulses; its frames stay within the instruction bound the board's stated times come
/// from (`f446_facts::ISR_BOUNDS`). Streamed one line per `ok` without the hold, a quiet host let the
/// queue run dry before each corner and never ran this frame.
#[test]
fn f446_worst_frame_stays_within_its_bound() {
    let elf = build_board(&NUCLEO_F446RE_QEMU).unwrap();
    let dir = workspace().join("target").join("f446-qemu-corners");
    let opts = f446::StreamOptions {
        queue_first: true,
        ..f446::StreamOptions::new(&["TIM2", "TIM5"], Duration::from_secs(60))
    };
    let s = f446::stream_with(&elf, &dir, programs::CORNERS, &opts).unwrap();
    for (line, got) in &s.answers {
        assert_eq!(
            got.last().map(String::as_str),
            Some("ok"),
            "{line}: {got:?}"
        );
    }
    let held = s.held_status.as_deref().unwrap_or("");
    assert!(held.starts_with("<Hold:0"), "{held}");
    assert_eq!(f446::mpos(held), Some([0.0; 3]), "{held}");

    let settings = MachineSettings::default().nc;
    let prog = analysis::load_program(programs::CORNERS, &settings).unwrap();
    let report = analysis::analyse(&prog, &settings, 0, &s.capture.pins);
    assert!(report.end_points_exact(), "{:?}", report.blocks);
    let edges = analysis::edges(0, &s.capture.pins);
    assert_eq!(
        analysis::compare_with_host(&prog, &settings, &edges.groups),
        None
    );
    assert_eq!(vcd::positions(0, &s.capture.pins), [0, 0, 0]);
    assert!(s.status.starts_with("<Idle"), "{}", s.status);

    let bounds = millac_qemu::f446_facts::ISR_BOUNDS;
    let (frames, pulses) = (&s.capture.handlers[0].1, &s.capture.handlers[1].1);
    let (fmax, pmax) = (frames.iter().max().unwrap(), pulses.iter().max().unwrap());
    println!("corners: TIM2 max {fmax} instructions, TIM5 max {pmax}");
    assert!(
        *fmax <= u64::from(bounds.frame_instructions),
        "frame ISR {fmax}"
    );
    assert!(
        *pmax <= u64::from(bounds.pulse_end_instructions),
        "pulse-end ISR {pmax}"
    );
}
