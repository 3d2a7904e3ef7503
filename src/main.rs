//! `prt`: the command line of wavelet-prt. See `prt --help` and the README.

fn main() {
    silence_device_select();
    std::process::exit(wavelet_prt::app::cli::main());
}

/// Mesa's Vulkan device-select layer prints "error: XDG_RUNTIME_DIR is invalid or not set" at
/// every instance wgpu creates on a machine without a login session (containers, ssh, CI). wgpu
/// picks its adapter itself, so the layer is turned off: when neither `NODEVICE_SELECT` nor a
/// valid `XDG_RUNTIME_DIR` is set, the program runs itself again, once, in place, with
/// `NODEVICE_SELECT=1` (setting a variable of the running process is not safe in Rust 2024).
fn silence_device_select() {
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        let session =
            std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir());
        if session || std::env::var_os("NODEVICE_SELECT").is_some() {
            return;
        }
        let Ok(exe) = std::env::current_exe() else {
            return;
        };
        // Returns only when the program could not be run again; it then goes on as it is.
        let _ = std::process::Command::new(exe)
            .args(std::env::args_os().skip(1))
            .env("NODEVICE_SELECT", "1")
            .exec();
    }
}
