//! Lays linear EXR images side by side in a captioned contact sheet, all tone-mapped with the
//! exposure of the last one (the reference), for documentation:
//! `cargo run --release --example image_sheet -- OUT.png COLUMNS "TITLE" IMG.exr=CAPTION ...`.
//! A caption may hold a `|` to split it over its two lines.

use wavelet_prt::output::film::{Image, ToneMap};
use wavelet_prt::output::sheet::{cells_at, write_sheet};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, columns, title, cells @ ..] = &args[..] else {
        eprintln!("usage: image_sheet OUT.png COLUMNS TITLE IMG.exr=CAPTION ...");
        std::process::exit(2);
    };
    let columns: usize = columns.parse().unwrap_or_else(|_| {
        eprintln!("{columns}: not a column count");
        std::process::exit(2)
    });
    let loaded: Vec<(Image, [String; 2])> = cells
        .iter()
        .map(|c| {
            let (path, caption) = c.split_once('=').unwrap_or((c, ""));
            let image = Image::load_exr(std::path::Path::new(path)).unwrap_or_else(|e| {
                eprintln!("{e}");
                std::process::exit(1)
            });
            let (a, b) = caption.split_once('|').unwrap_or((caption, ""));
            (image, [a.to_string(), b.to_string()])
        })
        .collect();
    let Some((reference, _)) = loaded.last() else {
        eprintln!("no images");
        std::process::exit(2)
    };
    let tone = ToneMap::auto(reference, None);
    let cells = cells_at(&loaded, tone);
    if let Err(e) = write_sheet(std::path::Path::new(out), columns, &cells, title) {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
