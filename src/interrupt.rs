//! Interrupts of a running render or study: the first Ctrl-C (SIGINT), or a SIGTERM or SIGHUP,
//! asks the work to stop and keep what is finished; a second one exits at once.
//!
//! On Unix the signal handler only writes the signal number to a pipe (write(2) is
//! async-signal-safe); a watcher thread reads it and acts in ordinary code: it raises the cancel
//! flag the first time, and the second time removes the temporary output files being written
//! and exits with 128 + the signal number, as a shell reports a process killed by it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

/// The signal that interrupted the program (0: none yet).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// SIGINT's number, the signal a Ctrl-C sends.
const SIGINT: i32 = 2;

/// The exit status for an interrupted run: 128 + the signal (130 for Ctrl-C, 143 for SIGTERM).
pub fn exit_code() -> i32 {
    match SIGNAL.load(Ordering::Relaxed) {
        0 => 128 + SIGINT,
        signal => 128 + signal,
    }
}

/// A name for messages.
pub fn signal_name() -> &'static str {
    match SIGNAL.load(Ordering::Relaxed) {
        15 => "SIGTERM",
        1 => "SIGHUP",
        _ => "Ctrl-C",
    }
}

/// What the watcher does with each signal received.
fn on_interrupt(cancel: &AtomicBool, signal: i32) {
    if cancel.swap(true, Ordering::Relaxed) {
        eprintln!("interrupted again: exiting at once");
        lumis::image_io::exit_removing_temporaries(128 + signal);
    }
    SIGNAL.store(signal, Ordering::Relaxed);
    eprintln!("interrupted: finishing what is in progress (interrupt again to exit at once)");
}

#[cfg(unix)]
mod platform {
    use std::sync::atomic::{AtomicI32, Ordering};

    /// Write end of the pipe the handler writes signal numbers to.
    static PIPE: AtomicI32 = AtomicI32::new(-1);

    extern "C" fn handler(signal: libc::c_int) {
        let fd = PIPE.load(Ordering::Relaxed);
        if fd >= 0 {
            let byte = signal as u8;
            // SAFETY: write(2) on a valid descriptor with a one-byte buffer; async-signal-safe.
            unsafe { libc::write(fd, (&byte as *const u8).cast(), 1) };
        }
    }

    /// Installs the handler for SIGINT, SIGTERM and SIGHUP; `on_signal` runs on a watcher
    /// thread for each signal received.
    pub fn install(on_signal: impl Fn(i32) + Send + 'static) -> std::io::Result<()> {
        let mut fds = [0 as libc::c_int; 2];
        // SAFETY: pipe(2) fills the two descriptors of a valid array.
        if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
            return Err(std::io::Error::last_os_error());
        }
        let (read_fd, write_fd) = (fds[0], fds[1]);
        PIPE.store(write_fd, Ordering::Relaxed);
        std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                loop {
                    let mut byte = 0u8;
                    // SAFETY: read(2) of one byte into a valid buffer.
                    let n = unsafe { libc::read(read_fd, (&mut byte as *mut u8).cast(), 1) };
                    match n {
                        1 => on_signal(byte as i32),
                        _ if std::io::Error::last_os_error().kind()
                            == std::io::ErrorKind::Interrupted => {}
                        _ => break,
                    }
                }
            })?;
        for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            // SAFETY: a zeroed sigaction with a handler of the right signature; SA_RESTART keeps
            // the program's own reads and writes from failing with EINTR.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = handler as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut action.sa_mask);
                if libc::sigaction(signal, &action, std::ptr::null_mut()) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
            }
        }
        Ok(())
    }
}

#[cfg(not(unix))]
mod platform {
    /// Ctrl-C only, through the ctrlc crate.
    pub fn install(on_signal: impl Fn(i32) + Send + 'static) -> std::io::Result<()> {
        ctrlc::set_handler(move || on_signal(super::SIGINT)).map_err(std::io::Error::other)
    }
}

/// Installs the handlers; the returned flag becomes true at the first interrupt.
pub fn install() -> std::io::Result<Arc<AtomicBool>> {
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    platform::install(move |signal| on_interrupt(&flag, signal))?;
    Ok(cancel)
}
