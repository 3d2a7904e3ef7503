//! `prt view`: the window, or with `--screenshot` the image it would show.

use super::*;
use crate::draw::vertex::Orbit;

/// Arguments of `prt view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Transport file (.prt), or a volume file (.prtv) for the volume path.
    pub file: PathBuf,
    /// Extra environments (.exr/.hdr or sun:ELEV,AZIM[,RADIUS]), besides the bundled ones.
    #[arg(long, num_args = 1..)]
    pub env: Vec<String>,
    /// Render one frame to this PNG without opening a window, then exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// wavelet, sh, full or sh-light (with --screenshot; default as `prt relight`).
    #[arg(long, value_parser = Method::from_str)]
    pub method: Option<Method>,
    /// Kept wavelet terms K (with --screenshot; default as `prt relight`, at most the file's
    /// 6·N²).
    #[arg(long)]
    pub terms: Option<usize>,
    /// none, area or transport (with --screenshot; default as `prt relight`).
    #[arg(long, value_parser = Weighting::from_str)]
    pub weighting: Option<Weighting>,
    /// SH order (with --screenshot; default the baked order, as `prt relight`).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// The local lights, as `prt relight` takes them (with --screenshot).
    #[command(flatten)]
    pub lights: LocalLightArgs,
    /// How the environment is turned (with --screenshot).
    #[command(flatten)]
    pub turn: TurnArgs,
    /// Exposure in stops (with --screenshot; default automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// SH and wavelet side by side (with --screenshot).
    #[arg(long)]
    pub compare: bool,
    /// SH and wavelet as one image split at this fraction of the width, SH on the left
    /// (with --screenshot; implies --compare).
    #[arg(long)]
    pub split: Option<f32>,
    /// Display curve after the exposure: clip, reinhard or aces (with --screenshot).
    #[arg(long, value_parser = parse_tone)]
    pub tone: Option<ToneCurve>,
    /// Add the error heat map against full beside each image (with --screenshot).
    #[arg(long)]
    pub error_map: bool,
    /// A per-vertex bake's camera turned from the bake's: AZIMUTH,ELEVATION in degrees, and
    /// optionally DISTANCE, a multiple of the bake camera's distance (with --screenshot).
    #[arg(long, allow_hyphen_values = true, value_parser = Orbit::from_str)]
    pub orbit: Option<Orbit>,
    /// A per-vertex bake with visibility: draw the glossy light by SH glossy transfer at this SH
    /// order (1 to 8) instead of the lobe per pixel, as `prt relight --sh-transfer` does (with
    /// --screenshot).
    #[arg(long)]
    pub sh_transfer: Option<usize>,
}

pub(super) fn view_cmd(a: ViewArgs) -> Result<()> {
    use crate::app::viewer::{Engine, LightState, env_entries, screenshot};
    let Some(out) = a.screenshot.clone() else {
        if a.method.is_some()
            || a.terms.is_some()
            || a.weighting.is_some()
            || a.sh_order.is_some()
            || !a.lights.is_empty()
            || a.turn.yaw != 0.0
            || a.turn.pitch != 0.0
            || a.exposure.is_some()
            || a.compare
            || a.error_map
            || a.split.is_some()
            || a.tone.is_some()
            || a.orbit.is_some()
            || a.sh_transfer.is_some()
        {
            return Err(PrtError::invalid(
                "viewer",
                "--method, --terms, --light, --yaw, --orbit, ... apply to --screenshot only (in \
                 the window, set them in the panel; drag the image of a per-vertex bake to \
                 orbit)",
            ));
        }
        if !a.file.exists() {
            return Err(PrtError::io(
                &a.file,
                std::io::Error::from(std::io::ErrorKind::NotFound),
            ));
        }
        return crate::app::viewer::run(&a.file, &a.env);
    };
    let mut inputs = env_files(&a.env);
    inputs.push(a.file.clone());
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(
        &out,
        &["png"],
        "a tone-mapped PNG (`prt relight -o IMG.exr` writes linear radiance)",
        &inputs,
    )?;
    check_light_flags(a.turn.yaw, a.turn.pitch, a.exposure)?;
    if let Some(f) = a.split {
        crate::flags::fraction("split", f)?;
    }
    if crate::volume::is_volume_file(&a.file) {
        if a.method.is_some()
            || a.terms.is_some()
            || a.weighting.is_some()
            || !a.lights.is_empty()
            || a.compare
            || a.error_map
            || a.split.is_some()
            || a.orbit.is_some()
            || a.sh_transfer.is_some()
        {
            return Err(PrtError::invalid(
                "viewer",
                "--method, --terms, --weighting, --light, --compare, --split, --error-map, \
                 --orbit and --sh-transfer apply to transport files; for a volume's views and cameras use `prt \
                 volume render`",
            ));
        }
        return volume_screenshot_cmd(&a, &out);
    }
    let (entries, light) = env_entries(&a.env);
    let transport = Transport::load(&a.file)?;
    let compare = a.compare || a.split.is_some();
    let panes = (1 + u64::from(compare)) * (1 + u64::from(a.error_map));
    check_screenshot_memory(&transport, panes)?;
    let mut engine = Engine::from_transport(&a.file, transport, entries)?;
    // The lights are checked before the first view is made; the turn is the first view's.
    let light_settings = a.lights.settings(&engine.transport.meta.lights)?;
    let mut state = engine.initial_state(LightState {
        rotation: a.turn.rotation(),
        ..light
    });
    state.set_lights(&engine.transport.meta.lights, &light_settings)?;
    state.relight.compare = compare;
    state.display.error_map = a.error_map;
    if let Some(f) = a.split {
        state.display.layout = crate::app::viewer::Layout::Split;
        state.display.split = f;
    }
    if let Some(t) = &a.tone {
        state.display.tone = *t;
    }
    if let Some(m) = &a.method {
        state.relight.method = *m;
    }
    // Given flags are checked as `relight` checks them; only the defaults are fitted to the file.
    let limits = engine.limits();
    if let Some(k) = a.terms {
        crate::flags::terms(k, engine.transport.meta.identity.cube_n as usize)?;
        state.relight.terms = k;
    }
    if let Some(w) = &a.weighting {
        state.relight.weighting = *w;
    }
    if let Some(o) = a.sh_order {
        if state.relight.method == Method::ShLight {
            if o == 0 || o > limits.sh_light_order {
                return Err(PrtError::invalid(
                    "SH order",
                    format!(
                        "{o}; through the light this file goes up to order {} (no more terms \
                         than its texels)",
                        limits.sh_light_order
                    ),
                ));
            }
        } else {
            crate::flags::sh_order(o, limits.sh_order)?;
        }
        state.relight.sh_order = o;
    }
    if let Some(order) = a.sh_transfer {
        transfer_visibility(&engine.transport)?;
        crate::relight::sh_transfer::check_order(order)?;
        state.display.sh_transfer = Some(order);
    }
    if let Some(o) = a.orbit {
        crate::draw::vertex::mesh_of(&engine.transport)?;
        state.orbit = o;
    }
    state.display.exposure = match a.exposure {
        Some(e) => e,
        None => engine.auto_exposure(&state)?,
    };
    let r = screenshot(&mut engine, &state, &out)?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    for p in &r.panes {
        let l = &p.linear;
        println!(
            "{}: {} terms, {:.2} M nonzeros touched, relight {:.2} ms, relative L2 vs full {}",
            l.title,
            l.terms,
            l.nonzeros_touched as f64 * 1e-6,
            l.relight_seconds * 1e3,
            l.rel_l2_percent()
        );
    }
    println!("wrote {}", out.display());
    Ok(())
}

/// Bytes a pixel of a screenshot takes at its peak, besides its panes: the backdrop (the
/// environment behind, 12, and the open coverage it is drawn for, 4) and one drawing in progress
/// (a 4-sample drawing's running sum and the sample drawn, colour and coverage, 16 each).
/// Counted from the buffers, not measured.
const SCREENSHOT_BYTES_PER_PIXEL: u64 = 48;
/// Bytes a pixel of each pane takes: its drawn image and the same over the backdrop (12 each),
/// its 8-bit RGB and its share of the captioned sheet (3 each).
const PANE_BYTES_PER_PIXEL: u64 = 30;

/// Refuses a screenshot of `t` with `panes` panes (at the size of the view, or of a per-vertex
/// bake's camera) larger than the memory this process can have, before any work.
fn check_screenshot_memory(t: &Transport, panes: u64) -> Result<()> {
    let (w, h) = crate::app::viewer::view_size(t);
    let per_pixel = SCREENSHOT_BYTES_PER_PIXEL + panes * PANE_BYTES_PER_PIXEL;
    crate::files::check_memory(
        "--screenshot",
        &format!(
            "a {w} x {h} screenshot of {panes} pane(s) ({per_pixel} bytes a pixel; a per-vertex \
             bake is drawn at any size by `prt relight --width --height`)"
        ),
        w as u64 * h as u64 * per_pixel,
    )
}

/// `prt view FILE.prtv --screenshot OUT.png`: the volume window's first frame.
fn volume_screenshot_cmd(a: &ViewArgs, out: &std::path::Path) -> Result<()> {
    use crate::app::viewer::{VolumeEngine, VolumeState, env_entries, volume_screenshot};
    let vt = crate::volume::VolumeTransfer::load(&a.file)?;
    let (w, h) = (vt.meta.width, vt.meta.height);
    let per_pixel = super::volume::VOLUME_BYTES_PER_PIXEL;
    crate::files::check_memory(
        "--screenshot",
        &format!("a {w} x {h} screenshot of the volume ({per_pixel} bytes a pixel)"),
        w as u64 * h as u64 * per_pixel,
    )?;
    let (entries, light) = env_entries(&a.env);
    let mut state = VolumeState {
        light,
        ..VolumeState::initial(&vt)
    };
    state.light.rotation = a.turn.rotation();
    if let Some(o) = a.sh_order {
        crate::flags::sh_order(o, vt.meta.sh_order)?;
        state.sh_order = o;
    }
    if let Some(t) = &a.tone {
        state.tone = *t;
    }
    let mut engine = VolumeEngine::new(vt, entries);
    state.exposure = match a.exposure {
        Some(e) => e,
        None => {
            let f = engine.render(&state)?;
            ToneMap::auto(&f.image, None).exposure
        }
    };
    let f = volume_screenshot(&mut engine, &state, out)?;
    println!(
        "volume {} view, SH order {}: march {:.1} ms on {}",
        state.view.name(),
        state.sh_order,
        f.march_seconds * 1e3,
        f.device
    );
    println!("wrote {}", out.display());
    Ok(())
}
