//! Checks of the Nucleo-F446RE firmware that need no board (host, CI): it builds in release, it
//! fits the flash and RAM budgets recorded in hal/nucleo-f446re/budget.txt, and its frame ISR
//! (TIM2) and pulse-end ISR (TIM5) contain no call and no panic path, as on the QEMU board.
use millac_qemu::elf;
use millac_qemu::firmware::{build_board, workspace, NUCLEO_F446RE};

/// `key = value` lines of the budget file (comments start with `#`).
fn budget(key: &str) -> u64 {
    let path = workspace().join("hal/nucleo-f446re/budget.txt");
    let text = std::fs::read_to_string(&path).unwrap();
    text.lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .filter_map(|l| l.split_once('='))
        .find(|(k, _)| k.trim() == key)
        .map(|(_, v)| v.trim().parse().unwrap())
        .unwrap_or_else(|| panic!("{key} missing in {}", path.display()))
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
    let m = elf::memory_use_in(&std::fs::read(&elf).unwrap(), 0x2000_0000).unwrap();
    let (flash, ram) = (budget("flash_bytes"), budget("ram_bytes"));
    println!(
        "flash {} of {flash} bytes, RAM {} of {ram} bytes",
        m.flash, m.ram
    );
    assert!(
        m.flash > 16 * 1024,
        "flash {} is implausibly small",
        m.flash
    );
    assert!(m.flash <= flash, "flash {} > budget {flash}", m.flash);
    assert!(m.ram <= ram, "RAM {} > budget {ram}", m.ram);
}
