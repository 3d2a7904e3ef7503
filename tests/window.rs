//! The viewer in a real window: `prt view` under an X server (Xvfb), captured with `xwd`. The
//! window must come up at its default size and draw the control panel and a lit image over the
//! environment behind the scene, with no error line. Without Xvfb and xwd the test is skipped with
//! a printed reason, or fails when `PRT_REQUIRE_DISPLAY=1`, as CI sets it.

mod common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A child process killed when dropped, so a failing assertion leaves nothing running.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn have(program: &str) -> bool {
    Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {program}"))
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// An RGB screen capture.
struct Capture {
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
}

impl Capture {
    fn at(&self, x: usize, y: usize) -> [u8; 3] {
        self.rgb[y * self.width + x]
    }
}

/// Parses an XWD dump of a 24-bit true-colour screen (32 bits a pixel), as Xvfb's is.
fn parse_xwd(bytes: &[u8]) -> Result<Capture, String> {
    let word = |i: usize| -> Result<u32, String> {
        bytes
            .get(4 * i..4 * i + 4)
            .map(|b| u32::from_be_bytes(b.try_into().unwrap()))
            .ok_or_else(|| format!("XWD header too short ({} bytes)", bytes.len()))
    };
    let (header, width, height) = (word(0)? as usize, word(4)? as usize, word(5)? as usize);
    let (lsb_first, bits, line) = (word(7)? == 0, word(11)?, word(12)? as usize);
    let colors = word(19)? as usize;
    let masks = (word(14)?, word(15)?, word(16)?);
    if bits != 32 || masks != (0xff0000, 0xff00, 0xff) {
        return Err(format!(
            "unexpected XWD layout: {bits} bits, masks {masks:x?}"
        ));
    }
    let start = header + 12 * colors;
    let data = bytes
        .get(start..start + line * height)
        .ok_or("XWD image data cut short")?;
    let mut rgb = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let p: [u8; 4] = data[y * line + 4 * x..y * line + 4 * x + 4]
                .try_into()
                .unwrap();
            let v = if lsb_first {
                u32::from_le_bytes(p)
            } else {
                u32::from_be_bytes(p)
            };
            rgb.push([(v >> 16) as u8, (v >> 8) as u8, v as u8]);
        }
    }
    Ok(Capture { width, height, rgb })
}

fn capture(display: &str) -> Option<Capture> {
    let out = Command::new("xwd")
        .args(["-root", "-silent", "-display", display])
        .output()
        .ok()?;
    parse_xwd(&out.stdout).ok()
}

/// What the window shows: the panel's left column and the image area to its right.
fn looks_drawn(c: &Capture) -> Result<(), String> {
    // The panel: egui's dark grey fills the left edge of the window.
    let panel = (0..c.height.min(700))
        .filter(|&y| {
            let p = c.at(10, y);
            p[0] > 15 && p[0] < 60 && p[0] == p[1] && p[1] == p[2]
        })
        .count();
    // The image: lit, coloured pixels right of the panel.
    let lit = (0..c.height)
        .flat_map(|y| (360..c.width.min(1280)).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = c.at(x, y);
            p.iter().map(|&v| v as u32).sum::<u32>() > 150
        })
        .count();
    if panel < 300 {
        return Err(format!("no control panel ({panel} rows of panel grey)"));
    }
    if lit < 20_000 {
        return Err(format!(
            "no lit image ({lit} lit pixels right of the panel)"
        ));
    }
    Ok(())
}

#[test]
fn the_viewer_draws_its_window_under_an_x_server() {
    let required = std::env::var("PRT_REQUIRE_DISPLAY").as_deref() == Ok("1");
    if !(have("Xvfb") && have("xwd")) {
        assert!(
            !required,
            "PRT_REQUIRE_DISPLAY=1 but Xvfb or xwd is missing (apt-get install xvfb x11-apps)"
        );
        eprintln!("skipped: Xvfb and xwd are needed (apt-get install xvfb x11-apps)");
        return;
    }
    // A display number no server holds (another test run's or a desktop's).
    let free = (90 + std::process::id() % 400..1000)
        .find(|n| {
            !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
                && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
        })
        .expect("a free X display number");
    let display = format!(":{free}");
    let dir = common::temp_dir("window");
    let _xvfb = Running(
        Command::new("Xvfb")
            .args([
                display.as_str(),
                "-screen",
                "0",
                "1280x800x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb starts"),
    );
    // The server takes a moment to listen; the viewer must not start before.
    let ready = Instant::now();
    while capture(&display).is_none() {
        assert!(
            ready.elapsed() < Duration::from_secs(30),
            "Xvfb {display} did not come up"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let runtime = dir.join("runtime");
    std::fs::create_dir_all(&runtime).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700)).unwrap();
    }
    let log = dir.join("view.log");
    let viewer = Running(
        Command::new(env!("CARGO_BIN_EXE_prt"))
            .arg("view")
            .arg(common::viewer_transport_path())
            .env("DISPLAY", &display)
            .env_remove("WAYLAND_DISPLAY")
            .env("XDG_RUNTIME_DIR", &runtime)
            .stdout(std::fs::File::create(&log).unwrap())
            .stderr(std::fs::File::create(dir.join("view.err")).unwrap())
            .spawn()
            .expect("prt view starts"),
    );
    let mut viewer = viewer;
    let start = Instant::now();
    let mut last = String::from("no capture");
    loop {
        std::thread::sleep(Duration::from_millis(500));
        if let Some(status) = viewer.0.try_wait().unwrap() {
            panic!(
                "prt view exited with {status}: {}",
                read(&dir.join("view.err"))
            );
        }
        match capture(&display).map(|c| looks_drawn(&c)) {
            Some(Ok(())) => {
                eprintln!("window drawn after {:.1} s", start.elapsed().as_secs_f64());
                break;
            }
            Some(Err(e)) => last = e,
            None => {}
        }
        assert!(
            start.elapsed() < Duration::from_secs(90),
            "the window never showed the panel and a lit image: {last}; stderr: {}",
            read(&dir.join("view.err"))
        );
    }
    let err = read(&dir.join("view.err"));
    assert!(
        !err.to_lowercase().contains("error"),
        "the viewer printed an error line: {err}"
    );
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_default()
}
