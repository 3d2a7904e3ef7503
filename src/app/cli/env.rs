//! `prt env`: what an environment map holds, as the engine reads it: its size, power and clamped
//! negatives, its SH coefficients, and the share of its Haar energy the best K terms capture.

use super::*;

/// Arguments of `prt env`.
#[derive(Args, Debug)]
pub struct EnvArgs {
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (see --list), or
    /// sun:ELEV,AZIM[,RADIUS].
    #[arg(required_unless_present = "list")]
    pub env: Option<String>,
    /// List the maps bundled into the binary, which every --env takes by name.
    #[arg(long)]
    pub list: bool,
    /// Cube face size for the Haar statistics.
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// SH order of the printed coefficients.
    #[arg(long, default_value_t = 3)]
    pub sh: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub(super) fn env_cmd(a: EnvArgs) -> Result<()> {
    let spec = match (&a.env, a.list) {
        (_, true) => {
            for m in crate::env::envmap::BUNDLED_MAPS {
                println!("{}", m.stem());
            }
            return Ok(());
        }
        (Some(spec), false) => spec,
        (None, false) => {
            return Err(PrtError::invalid(
                "env",
                "give an environment, or --list for the bundled maps",
            ));
        }
    };
    let env = load_env(spec)?;
    let power = env.power();
    let sh = env.project_sh(a.sh, EnvRotation::default())?;
    let cube = env.to_cube(a.cube, EnvRotation::default())?;
    let light = WaveletLight::from_cube(&cube)?;
    let energy: Vec<f64> = light
        .coeffs
        .iter()
        .map(|c| c.iter().map(|v| (*v as f64).powi(2)).sum())
        .collect();
    let total: f64 = energy.iter().sum();
    let mut sorted = energy.clone();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let ks: Vec<usize> = [1, 10, 50, 200, 1000]
        .into_iter()
        .filter(|&k| k <= sorted.len())
        .collect();
    let captured: Vec<(usize, f64)> = ks
        .iter()
        .map(|&k| {
            (
                k,
                sorted[..k].iter().sum::<f64>() / total.max(f64::MIN_POSITIVE),
            )
        })
        .collect();
    if a.json {
        let obj = serde_json::json!({
            "source": env.source,
            "width": env.width,
            "height": env.height,
            "negatives_clamped": env.negatives_clamped,
            "negative_share": env.negative_share(),
            "power": power,
            "sh_order": a.sh,
            "sh": sh,
            "cube_n": a.cube,
            "haar_energy_captured": captured.iter().map(|(k, f)| serde_json::json!({"k": k, "fraction": f})).collect::<Vec<_>>(),
        });
        println!("{obj}");
        return Ok(());
    }
    println!("environment   {}", env.source);
    println!("size          {} x {}", env.width, env.height);
    if env.negatives_clamped > 0 {
        println!(
            "negatives     {} samples read as 0 (the lowest {:.2e}, {:.4}% of Σ |L| Ω)",
            env.negatives_clamped,
            env.lowest_negative,
            100.0 * env.negative_share()
        );
    }
    println!(
        "power         R {:.4}  G {:.4}  B {:.4}  (Σ L Ω)",
        power[0], power[1], power[2]
    );
    println!("SH order {}    L_i = ∫ L Y_i dω, index l(l+1)+m:", a.sh);
    for (i, c) in sh.iter().enumerate() {
        let l = (i as f64).sqrt() as usize;
        let m = i as i64 - (l * (l + 1)) as i64;
        println!(
            "  l={l} m={m:+}  {:>12.5} {:>12.5} {:>12.5}",
            c[0], c[1], c[2]
        );
    }
    println!("Haar energy captured by the best K terms (N = {}):", a.cube);
    for (k, f) in captured {
        println!("  K = {k:>5}  {:.4}%", 100.0 * f);
    }
    Ok(())
}
