//! The container image of the README's Kubernetes recipe, checked without a container engine:
//! the Containerfile's syntax and stages, that its final stage holds every library the built
//! binary links, and that the README builds it under the name the recipe runs.

use std::path::Path;

fn read(name: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(name)).unwrap()
}

/// The Containerfile's instructions: (keyword, arguments), continuation lines joined.
fn instructions() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut pending = String::new();
    for line in read("Containerfile").lines() {
        let t = line.trim();
        if pending.is_empty() && (t.is_empty() || t.starts_with('#')) {
            continue;
        }
        match t.strip_suffix('\\') {
            Some(part) => {
                pending.push_str(part);
                pending.push(' ');
            }
            None => {
                pending.push_str(t);
                let (k, rest) = pending.split_once(' ').unwrap_or((&pending, ""));
                out.push((k.to_string(), rest.trim().to_string()));
                pending.clear();
            }
        }
    }
    assert!(
        pending.is_empty(),
        "the Containerfile ends in a continuation"
    );
    out
}

#[test]
fn the_containerfile_builds_in_one_stage_and_runs_from_a_slim_one() {
    const KNOWN: [&str; 12] = [
        "FROM",
        "RUN",
        "COPY",
        "ENV",
        "USER",
        "WORKDIR",
        "CMD",
        "ARG",
        "LABEL",
        "ENTRYPOINT",
        "EXPOSE",
        "VOLUME",
    ];
    let ins = instructions();
    for (k, _) in &ins {
        assert!(KNOWN.contains(&k.as_str()), "unknown instruction {k}");
    }
    let froms: Vec<&String> = ins
        .iter()
        .filter(|(k, _)| k == "FROM")
        .map(|(_, a)| a)
        .collect();
    assert_eq!(froms.len(), 2, "{froms:?}");
    assert!(froms[0].ends_with(" AS build") && froms[0].contains("rust:"));
    // The run stage: Mesa's software Vulkan driver, the binary from the build stage, a JSON
    // command.
    let run_stage = &ins[ins.iter().rposition(|(k, _)| k == "FROM").unwrap()..];
    assert!(
        run_stage
            .iter()
            .any(|(k, a)| k == "RUN" && a.contains("mesa-vulkan-drivers"))
    );
    assert!(run_stage.iter().any(|(k, a)| k == "COPY"
        && a.starts_with("--from=build ")
        && a.contains("target/release/prt /usr/local/bin/prt")));
    let build_stage = &ins[..ins.len() - run_stage.len()];
    assert!(
        build_stage
            .iter()
            .any(|(k, a)| k == "RUN" && a.contains("cargo build --release --locked --bin prt"))
    );
    let (_, cmd) = run_stage.iter().find(|(k, _)| k == "CMD").unwrap();
    let cmd: Vec<String> = serde_json::from_str(cmd).expect("CMD is a JSON array");
    assert_eq!(cmd[0], "prt");
    assert!(run_stage.iter().any(|(k, a)| k == "USER" && a != "root"));
    // The build context leaves out the build outputs.
    let ignore = read(".dockerignore");
    assert!(ignore.lines().any(|l| l.trim() == "target"));
}

#[test]
fn the_readme_builds_the_image_the_kubernetes_recipe_runs() {
    let readme = read("README.md");
    let image = "your-registry/wavelet-prt:latest";
    assert!(readme.contains(&format!("image: {image}")));
    assert!(
        readme.contains(&format!("build -f Containerfile -t {image} .")),
        "the README does not say how to build {image}"
    );
    assert!(read("Containerfile").contains(&format!("-t {image} .")));
}

/// Libraries a Debian slim image has without installing anything (the C library's parts and
/// the GCC runtime).
const BASE_IMAGE_LIBRARIES: [&str; 8] = [
    "linux-vdso.so.1",
    "libc.so.6",
    "libm.so.6",
    "libgcc_s.so.1",
    "libdl.so.2",
    "libpthread.so.0",
    "librt.so.1",
    "ld-linux-x86-64.so.2",
];

#[test]
fn the_container_image_holds_what_the_binary_links() {
    let out = match std::process::Command::new("ldd")
        .arg(env!("CARGO_BIN_EXE_prt"))
        .output()
    {
        Ok(out) => out,
        Err(e) => {
            eprintln!("ldd is not available ({e}): the binary's libraries are not checked");
            return;
        }
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let libraries: Vec<&str> = text
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(|l| l.rsplit('/').next().unwrap_or(l))
        .collect();
    assert!(libraries.contains(&"libc.so.6"), "{text}");
    for lib in libraries {
        assert!(
            BASE_IMAGE_LIBRARIES.contains(&lib),
            "prt links {lib}, which the Containerfile's run stage does not install:\n{text}"
        );
    }
}
