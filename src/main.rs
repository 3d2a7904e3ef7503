//! `prt`: the command line of wavelet-prt. See `prt --help` and the README.

fn main() {
    std::process::exit(wavelet_prt::app::cli::main());
}
