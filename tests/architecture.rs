//! The house rules of ARCHITECTURE.md, checked on the source: every `crate::` path in library code
//! runs from a stage to the same stage or one before it, the modules import each other without a
//! loop, no source file outgrows about 800 lines (its test module aside), and `unsafe` stays in
//! the one module that needs it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The stages in import order: a module may use its own stage and those before it. `api` may
/// use every engine stage and only `app` may use it; `app` may use everything; nothing else may
/// use `app`.
const STAGES: [&[&str]; 13] = [
    &["error", "files", "conventions", "names"],
    &["math"],
    &["flags"],
    &["output"],
    &["gpu"],
    &["medium"],
    &["scene"],
    &["env"],
    &["store"],
    &["bake"],
    &["relight", "draw", "volume"],
    &["api"],
    &["app"],
];

const MAX_LINES: usize = 800;

fn stage_rank(module: &str) -> Option<usize> {
    let top = module.split("::").next()?;
    STAGES.iter().position(|s| s.contains(&top))
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `src/env/envmap.rs` -> `env::envmap`, `src/store/mod.rs` -> `store`.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .filter(|c| c != "mod")
        .collect();
    parts.join("::")
}

/// The library code of a file with its true (1-based) line numbers: its lines up to an inline
/// `#[cfg(test)]` module, comments dropped. Test files and test helpers are not library code.
fn library_lines(text: &str) -> Vec<(usize, &str)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines
                .get(i + 1)
                .is_some_and(|n| n.trim_start().starts_with("mod tests {"))
        {
            break;
        }
        if !t.starts_with("//") {
            out.push((i + 1, *l));
        }
    }
    out
}

/// The module `super` names from `module`: its parent (`a::b` -> `a`, `a` -> the crate root,
/// ""), whether `module` is a file or a folder's `mod.rs`.
fn parent(module: &str) -> &str {
    module.rsplit_once("::").map_or("", |(p, _)| p)
}

/// The crate paths a line of `module` names: `crate::a::b`, `super::a` (resolved from the
/// module, chains included) and, in a `use` or `pub use`, a path that starts at one of the
/// module's own children (`pub use child::Item`).
fn paths_in(line: &str, module: &str, modules: &BTreeSet<String>) -> Vec<String> {
    let is_path_char = |c: char| c.is_alphanumeric() || c == '_' || c == ':';
    let mut found = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find(|c: char| c.is_alphabetic() || c == '_') {
        let start = &rest[i..];
        let end = start
            .find(|c: char| !is_path_char(c))
            .unwrap_or(start.len());
        let word = start[..end].trim_end_matches(':');
        // Only whole words: `supercrate::` is not `crate::`.
        let boundary = i == 0 || !is_path_char(rest[..i].chars().last().unwrap_or(' '));
        if boundary {
            if let Some(tail) = word.strip_prefix("crate::") {
                found.push(tail.to_string());
            } else if word == "super" || word.starts_with("super::") {
                // `super::a`, `super::super::a`, and `super::*` or `super::{..}` (the word
                // `super` alone), which name the parent itself.
                let mut base = module;
                let mut tail = word;
                while tail == "super" || tail.starts_with("super::") {
                    base = parent(base);
                    tail = tail["super".len()..].trim_start_matches(':');
                }
                found.push(match (base.is_empty(), tail.is_empty()) {
                    (_, true) => base.to_string(),
                    (true, false) => tail.to_string(),
                    (false, false) => format!("{base}::{tail}"),
                });
            }
        }
        rest = &start[end..];
    }
    let t = line.trim_start();
    if let Some(used) = t
        .strip_prefix("pub use ")
        .or_else(|| t.strip_prefix("use "))
    {
        let first = used.split("::").next().unwrap_or("");
        let child = format!("{module}::{first}");
        if !module.is_empty() && modules.contains(&child) {
            let path = used.trim_end_matches(';');
            found.push(format!("{module}::{path}"));
        }
    }
    found
}

fn is_test_file(module: &str) -> bool {
    module.ends_with("tests") || module.ends_with("test_support")
}

/// The module a `crate::a::b::c` path names: the longest known module that prefixes it.
fn target_of<'a>(path: &str, modules: &'a BTreeSet<String>) -> Option<&'a String> {
    modules
        .iter()
        .filter(|m| path == m.as_str() || path.starts_with(&format!("{m}::")))
        .max_by_key(|m| m.len())
}

struct House {
    /// Module -> (line, the module it uses) for every `crate::` path in library code.
    uses: BTreeMap<String, Vec<(usize, String)>>,
    /// Module -> library lines (test module aside, comments included).
    lengths: BTreeMap<String, usize>,
}

fn house() -> House {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(&src, f)).collect();
    let mut uses = BTreeMap::new();
    let mut lengths = BTreeMap::new();
    for f in &files {
        let module = module_of(&src, f);
        if is_test_file(&module) || module == "main" || module == "lib" {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        let test_start = text
            .lines()
            .collect::<Vec<_>>()
            .windows(2)
            .position(|w| w[0].trim() == "#[cfg(test)]" && w[1].trim() == "mod tests {")
            .unwrap_or(usize::MAX);
        lengths.insert(module.clone(), text.lines().count().min(test_start));
        let mut found = Vec::new();
        for (n, line) in library_lines(&text) {
            for path in paths_in(line, &module, &modules) {
                if let Some(t) = target_of(&path, &modules)
                    && *t != module
                {
                    found.push((n, t.clone()));
                }
            }
        }
        uses.insert(module, found);
    }
    House { uses, lengths }
}

#[test]
fn every_module_belongs_to_a_stage() {
    let h = house();
    let strays: Vec<&String> = h.uses.keys().filter(|m| stage_rank(m).is_none()).collect();
    assert!(
        strays.is_empty(),
        "modules in no stage of ARCHITECTURE.md: {strays:?}"
    );
}

#[test]
fn every_module_file_is_named_in_the_architecture() {
    // A module is named where its last part stands in backticks (`envmap`, `resample/`), so
    // that the map of the stages lists every room of the house.
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("ARCHITECTURE.md"))
            .unwrap();
    let named =
        |name: &str| text.contains(&format!("`{name}`")) || text.contains(&format!("`{name}/`"));
    let h = house();
    let unnamed: Vec<&String> = h
        .lengths
        .keys()
        .filter(|m| m.rsplit("::").next().is_some_and(|last| !named(last)))
        .collect();
    assert!(
        unnamed.is_empty(),
        "modules ARCHITECTURE.md does not name: {unnamed:?}"
    );
}

#[test]
fn no_stage_imports_a_later_one() {
    let h = house();
    let mut wrong = Vec::new();
    for (m, uses) in &h.uses {
        let (Some(from), true) = (stage_rank(m), !m.starts_with("app")) else {
            continue;
        };
        for (line, t) in uses {
            if stage_rank(t).is_some_and(|to| to > from) {
                wrong.push(format!("{m} (line {line}) uses {t}"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the stage order:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn modules_import_each_other_without_a_loop() {
    let h = house();
    let graph: BTreeMap<&str, BTreeSet<&str>> = h
        .uses
        .iter()
        .map(|(m, u)| {
            // A folder's module re-exports its children and a child uses its folder's
            // (`use super::*`): that is one module's layout, not a loop between modules.
            let related =
                |t: &str| t.starts_with(&format!("{m}::")) || m.starts_with(&format!("{t}::"));
            let targets = u.iter().map(|(_, t)| t.as_str()).filter(|t| !related(t));
            (m.as_str(), targets.collect())
        })
        .collect();
    // Depth-first search with colours; a grey target is a loop.
    fn visit<'a>(
        m: &'a str,
        graph: &BTreeMap<&'a str, BTreeSet<&'a str>>,
        colour: &mut BTreeMap<&'a str, u8>,
        stack: &mut Vec<&'a str>,
        loops: &mut Vec<String>,
    ) {
        colour.insert(m, 1);
        stack.push(m);
        for &t in graph.get(m).into_iter().flatten() {
            match colour.get(t) {
                Some(1) => {
                    let at = stack.iter().position(|s| *s == t).unwrap_or(0);
                    loops.push(format!("{} -> {t}", stack[at..].join(" -> ")));
                }
                Some(_) => {}
                None => visit(t, graph, colour, stack, loops),
            }
        }
        stack.pop();
        colour.insert(m, 2);
    }
    let mut colour = BTreeMap::new();
    let mut loops = Vec::new();
    for &m in graph.keys() {
        if !colour.contains_key(m) {
            visit(m, &graph, &mut colour, &mut Vec::new(), &mut loops);
        }
    }
    assert!(loops.is_empty(), "import loops:\n{}", loops.join("\n"));
}

#[test]
fn no_source_file_outgrows_the_limit() {
    let h = house();
    let long: Vec<String> = h
        .lengths
        .iter()
        .filter(|(_, n)| **n > MAX_LINES)
        .map(|(m, n)| format!("{m}: {n} lines"))
        .collect();
    assert!(
        long.is_empty(),
        "files over {MAX_LINES} lines (test modules aside):\n{}",
        long.join("\n")
    );
}

/// The one module allowed `unsafe`, with its own submodules (it calls AVX2 intrinsics behind
/// run-time detection); `Cargo.toml` denies it everywhere else, and this keeps the exception
/// from spreading.
const UNSAFE_ALLOWED: &str = "relight::strip_kernel";

#[test]
fn only_the_strip_kernel_allows_unsafe_code() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        if text.contains("unsafe_code") || text.contains("unsafe ") {
            found.push(module_of(&src, f));
        }
    }
    let inside = |m: &String| m == UNSAFE_ALLOWED || m.starts_with(&format!("{UNSAFE_ALLOWED}::"));
    assert!(
        found.iter().all(inside) && found.iter().any(|m| m == UNSAFE_ALLOWED),
        "modules that allow or use unsafe code: {found:?}"
    );
}

#[test]
fn the_checker_sees_a_planted_violation() {
    // The rules above must be able to fail: a later stage named from an earlier one, by
    // `crate::` or by `super::`, found on its true line; a test module's imports ignored.
    let text = "//! Doc.\n\nuse crate::app::studies::demo;\n#[cfg(test)]\nmod tests {\nuse crate::app::cli;\n}\n";
    let lines = library_lines(text);
    assert_eq!(lines, vec![(2, ""), (3, "use crate::app::studies::demo;")]);
    assert!(stage_rank("app::studies::demo") > stage_rank("math::sh"));
    let modules: BTreeSet<String> = [
        "app",
        "app::studies::demo",
        "flags",
        "light",
        "light::resample",
        "light::resample::cache",
    ]
    .map(String::from)
    .into();
    assert_eq!(
        target_of("app::studies::demo::write_assets", &modules).map(String::as_str),
        Some("app::studies::demo")
    );
    let targets = |line: &str, module: &str| -> Vec<String> {
        paths_in(line, module, &modules)
            .iter()
            .filter_map(|p| target_of(p, &modules).cloned())
            .collect()
    };
    // `super::` from a top-level module reaches the crate root, and so any stage.
    assert_eq!(
        targets("use super::app::studies::demo::run;", "flags"),
        ["app::studies::demo"]
    );
    // Chains climb one module each.
    assert_eq!(
        targets(
            "let x = super::super::resample::f();",
            "light::resample::cache"
        ),
        ["light::resample"]
    );
    assert_eq!(
        targets("use super::*;", "light::resample::cache"),
        ["light::resample"]
    );
    // A re-export of a child is a use of it; a word that merely ends in `crate` is not a path.
    assert_eq!(
        targets("pub use cache::Cache;", "light::resample"),
        ["light::resample::cache"]
    );
    assert!(targets("let supercrate::x = 1;", "flags").is_empty());
}
