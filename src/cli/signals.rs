//! Clean exit on SIGINT, SIGTERM and SIGHUP: the output is written through a temporary file in its
//! directory (`bvhc_loader::write::write_atomic`), which an interrupted run would leave behind. A watcher thread waits
//! for the signals; when one arrives it removes this process's temporary files in the output's directory and
//! exits with 128 + the signal number, as a shell reports a process killed by it. The output itself is
//! untouched: the rename that replaces it either happened or did not.

use std::path::Path;

/// Starts the watcher for a command that writes into `output`'s directory. Failing to install it (no
/// threads, say) only loses the clean-up, so it is not an error.
pub fn clean_up_on_signal(output: &Path) {
    clean_up_on_signal_in(&[output.to_path_buf()]);
}

/// [`clean_up_on_signal`] for a command that writes all of `outputs` (`bvhc batch`): each of their directories
/// is swept once.
#[cfg(unix)]
pub fn clean_up_on_signal_in(outputs: &[std::path::PathBuf]) {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut directories: Vec<_> = outputs.iter().map(|o| bvhc::loader::write::directory_of(o).to_path_buf()).collect();
    directories.sort();
    directories.dedup();
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else { return };
    let _ = std::thread::Builder::new().name("signals".to_string()).spawn(move || {
        if let Some(signal) = signals.forever().next() {
            for directory in &directories {
                bvhc::loader::write::remove_own_temporary_files(directory);
            }
            std::process::exit(128 + signal);
        }
    });
}

/// Without Unix signals there is nothing to install; stale files are swept by the next write.
#[cfg(not(unix))]
pub fn clean_up_on_signal_in(_outputs: &[std::path::PathBuf]) {}
