//! Progress bars for the host tool's long commands (host: the CLI opens a bar around a run with
//! [`with_bar`]; the runs report into the bar of their own thread with [`update`] and
//! [`stage`]). Each bar shows the blocks done of the total, the virtual time simulated, the
//! ratio to real time and the time left. Bars draw on stderr only when it is a terminal
//! (indicatif hides them otherwise) and never with `--quiet` ([`set_quiet`]); without a bar
//! (the library in tests, a pipe) [`update`] is one thread-local read. Runs under QEMU show
//! their virtual time against `check`'s estimate ([`with_clock`], [`clock`]).
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

static QUIET: AtomicBool = AtomicBool::new(false);
static BARS: OnceLock<MultiProgress> = OnceLock::new();

std::thread_local! {
    /// This thread's bar and when it started, while [`with_bar`] runs.
    static BAR: RefCell<Option<(ProgressBar, Instant)>> = const { RefCell::new(None) };
}

/// `--quiet`: no bars at all.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

fn bars() -> &'static MultiProgress {
    BARS.get_or_init(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()))
}

/// Runs `f` with a bar named `label` of `total` blocks on this thread (none with `--quiet`);
/// the bar is cleared when `f` returns.
pub fn with_bar<T>(label: &str, total: usize, f: impl FnOnce() -> T) -> T {
    if QUIET.load(Ordering::Relaxed) {
        return f();
    }
    let bar = bars().add(ProgressBar::new(total as u64));
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix:>22} [{bar:24}] {pos}/{len} blocks  {msg}  eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_prefix(label.to_string());
    BAR.with(|b| *b.borrow_mut() = Some((bar.clone(), Instant::now())));
    let out = f();
    BAR.with(|b| *b.borrow_mut() = None);
    bar.finish_and_clear();
    out
}

/// A run on this thread has done `blocks` blocks and simulated `virtual_s` seconds (NaN: a
/// stage that simulates no time, the oracle's walk).
pub fn update(blocks: usize, virtual_s: f64) {
    BAR.with(|b| {
        if let Some((bar, started)) = b.borrow().as_ref() {
            bar.set_position(blocks as u64);
            let wall = started.elapsed().as_secs_f64();
            if !virtual_s.is_finite() {
                bar.set_message("");
            } else if wall > 0.0 {
                bar.set_message(format!(
                    "{virtual_s:.0} s virtual, {:.0}x real time",
                    virtual_s / wall
                ));
            }
        }
    });
}

/// The run on this thread has `total` blocks (known once its program is read).
pub fn set_total(total: usize) {
    BAR.with(|b| {
        if let Some((bar, _)) = b.borrow().as_ref() {
            bar.set_length(total as u64);
        }
    });
}

/// The run on this thread begins a new stage (the comparison's programmed feeds, the oracle,
/// the safe feed): the bar starts again under `label`.
pub fn stage(label: &str) {
    BAR.with(|b| {
        if let Some((bar, started)) = b.borrow_mut().as_mut() {
            bar.set_prefix(label.to_string());
            bar.set_position(0);
            bar.reset_eta();
            *started = Instant::now();
        }
    });
}

/// The bar of a run under QEMU (its plant samples on the co-simulation's bridge thread, not on
/// the thread that opened the bar), with when it started and the virtual time it last showed.
static CLOCK: std::sync::Mutex<Option<(ProgressBar, Instant, f64)>> = std::sync::Mutex::new(None);

/// Runs `f`, a run under QEMU of a program the frame takes `estimate_s` seconds to run (`check`'s
/// estimate; 0: unknown), with a bar of its virtual time against the estimate (none with
/// `--quiet`); [`clock`] moves it from any thread. Cleared when `f` returns.
pub fn with_clock<T>(label: &str, estimate_s: f64, f: impl FnOnce() -> T) -> T {
    if QUIET.load(Ordering::Relaxed) {
        return f();
    }
    // In tenths of a second of virtual time.
    let bar = bars().add(ProgressBar::new((estimate_s * 10.0).ceil().max(0.0) as u64));
    bar.set_style(
        ProgressStyle::with_template("{prefix:>22} [{bar:24}] {msg}  elapsed {elapsed}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_prefix(label.to_string());
    bar.set_message(format!("0 of {estimate_s:.0} s virtual (estimated)"));
    if let Ok(mut c) = CLOCK.lock() {
        *c = Some((bar.clone(), Instant::now(), 0.0));
    }
    let out = f();
    if let Ok(mut c) = CLOCK.lock() {
        *c = None;
    }
    bar.finish_and_clear();
    out
}

/// The run under QEMU has simulated `virtual_s` seconds (from any thread; the bar moves every
/// tenth of a second of virtual time).
pub fn clock(virtual_s: f64) {
    let Ok(mut c) = CLOCK.lock() else { return };
    let Some((bar, started, shown)) = c.as_mut() else {
        return;
    };
    if virtual_s < *shown + 0.1 {
        return;
    }
    *shown = virtual_s;
    bar.set_position((virtual_s * 10.0) as u64);
    let wall = started.elapsed().as_secs_f64();
    let estimate = bar.length().unwrap_or(0) as f64 / 10.0;
    bar.set_message(format!(
        "{virtual_s:.1} of {estimate:.0} s virtual (estimated), {:.2}x real time",
        virtual_s / wall.max(1e-9)
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--quiet` is global: the tests that open bars take turns.
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

    /// Without a bar, updates do nothing; with one, the run's result comes back and the bar is
    /// gone afterwards (it draws nowhere: the tests' stderr is not a terminal).
    #[test]
    fn a_bar_lives_only_around_its_run() {
        let _turn = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
        update(3, 1.0);
        assert!(BAR.with(|b| b.borrow().is_none()));
        let r = with_bar("test", 10, || {
            update(4, 2.0);
            stage("next");
            BAR.with(|b| {
                let b = b.borrow();
                let (bar, _) = b.as_ref().expect("a bar");
                (bar.position(), bar.prefix())
            })
        });
        assert_eq!(r, (0, "next".to_string()));
        assert!(BAR.with(|b| b.borrow().is_none()));
        set_quiet(true);
        let r = with_bar("quiet", 10, || BAR.with(|b| b.borrow().is_none()));
        set_quiet(false);
        assert!(r, "--quiet: no bar");
    }

    /// The clock moves from another thread while its run is open and by tenths of a second; it
    /// is gone afterwards.
    #[test]
    fn the_clock_moves_from_any_thread_while_its_run_is_open() {
        let _turn = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
        clock(5.0);
        let shown = || {
            CLOCK
                .lock()
                .unwrap()
                .as_ref()
                .map(|c| (c.0.position(), c.2))
        };
        assert_eq!(shown(), None);
        let r = with_clock("run", 60.0, || {
            std::thread::spawn(|| {
                clock(2.55);
                clock(2.6);
            })
            .join()
            .unwrap();
            shown()
        });
        assert_eq!(
            r,
            Some((25, 2.55)),
            "moved to 2.55 s, not again 0.05 s later"
        );
        assert_eq!(shown(), None);
    }
}
