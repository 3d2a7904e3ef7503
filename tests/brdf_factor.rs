//! `prt brdf`: the in-out factorisation's table and plot, and its argument checks.

mod common;

use common::{prt, temp_dir};

#[test]
fn prt_brdf_writes_the_error_table_and_plot() {
    let dir = temp_dir("brdf-factor");
    let out = dir.join("out");
    let (code, text) = prt(&[
        "brdf",
        "--out",
        out.to_str().unwrap(),
        "--resolution",
        "8",
        "--terms",
        "4",
        "--roughness",
        "0.2,0.5",
    ]);
    assert_eq!(code, 0, "{text}");
    let md = std::fs::read_to_string(out.join("brdf_factors.md")).unwrap();
    // One row per term, one column per roughness, and the errors falling down each column.
    let rows: Vec<Vec<f64>> = md
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("% |") && !l.contains("error"))
        .map(|l| {
            l.split('|')
                .skip(2)
                .filter_map(|c| c.trim().trim_end_matches('%').parse().ok())
                .collect()
        })
        .filter(|r: &Vec<f64>| r.len() == 2)
        .collect();
    assert_eq!(rows.len(), 4, "{md}");
    for pair in rows.windows(2) {
        assert!(pair[1][0] < pair[0][0] && pair[1][1] < pair[0][1], "{md}");
    }
    // The rougher lobe is the smoother one: fewer terms for the same error.
    assert!(rows[1][1] < rows[1][0], "{md}");
    assert!(out.join("brdf_factors.png").is_file());
    // A roughness out of range is named.
    let (code, text) = prt(&[
        "brdf",
        "--out",
        out.to_str().unwrap(),
        "--roughness",
        "0.001",
    ]);
    assert_ne!(code, 0);
    assert!(text.contains("--roughness"), "{text}");
}
