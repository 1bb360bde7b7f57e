//! SIGINT and SIGTERM for the host tool's commands (host: the signal handler stores the signal;
//! the command's threads and loops read it): `run`, `demo`, `host` and `serve` install the
//! handler ([`install`]) so that an interrupt ends the work early and the command still writes
//! the report of what was done (summary.json with `completed` false and `interrupted`), instead
//! of dying with no report. Without [`install`] (the library in tests) nothing is ever received.
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Arc;

/// The signal received (0: none). An atomic store is async-signal-safe.
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    if SIGNAL.swap(sig, Ordering::SeqCst) != 0 {
        // A second signal: the default action, at once (the report is given up).
        // SAFETY: signal(2) and raise(3) are async-signal-safe.
        unsafe {
            libc::signal(sig, libc::SIG_DFL);
            libc::raise(sig);
        }
    }
}

/// Installs the handler for SIGINT and SIGTERM: the first one is stored (the command ends its
/// work early and writes its report); a second one ends the process at once, as without the
/// handler. A signal ignored when the tool starts stays ignored.
pub fn install() {
    let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    for sig in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: installs a handler that only stores an atomic (or re-raises); a signal the
        // parent ignores (SIGINT for a shell's background job) stays ignored.
        unsafe {
            if libc::signal(sig, handler) == libc::SIG_IGN {
                libc::signal(sig, libc::SIG_IGN);
            }
        }
    }
}

/// The signal received since [`install`], if any.
pub fn received() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// `SIGINT`, `SIGTERM` (or `signal N`).
pub fn name(sig: i32) -> String {
    match sig {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        n => format!("signal {n}"),
    }
}

/// A flag set once a signal has been received (a thread polls every 20 ms), for the work that
/// stops on a flag (a QEMU capture's `stop`).
pub fn flag() -> Arc<AtomicBool> {
    let f = Arc::new(AtomicBool::new(false));
    let set = f.clone();
    std::thread::spawn(move || {
        while received().is_none() {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        set.store(true, Ordering::SeqCst);
    });
    f
}
