//! One set of defaults: every `[default: X]` of the command line against what README.md and
//! docs/guide/*.md say of it, `prt bake`'s against the demo's bake, `prt relight`'s against the
//! viewer's first view; `prt view --screenshot` under the relight flags; relative errors shown in
//! percent.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{s, temp_dir};
use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};
use wavelet_prt::app::studies::demo::{DEMO_SH_ORDERS, demo_settings};
use wavelet_prt::app::viewer::{Engine, ViewerApp, env_entries};
use wavelet_prt::bake::BakeSettings;
use wavelet_prt::output::text::CAPTION_HEIGHT;

/// A command's flags and the `[default: X]` its help gives each.
type Defaults = BTreeMap<String, String>;

/// Indent below which a help line starts an entry (a flag, an argument, a heading): clap indents
/// a flag by 2 or 6 and a description on lines of its own by 10.
const ENTRY_INDENT: usize = 8;

/// How far after a flag the documentation may state its default, in bytes.
const STATEMENT_REACH: usize = 160;

/// Words that, before "default", make it no flag's default ("the default edge length", "by
/// default").
const NOT_A_STATEMENT: [&str; 5] = ["the", "a", "by", "its", "their"];

/// Words that follow "default" without being a value ("default order 3", "default: the width").
const NOT_A_VALUE: [&str; 12] = [
    "the", "a", "an", "of", "order", "settings", "is", "when", "with", "for", "in", "on",
];

/// The environment of the command-line tests: the procedural sun, the same in every run.
const SUN: &str = "sun:30,45";

/// `prt COMMAND --help`.
fn help(command: &[&str]) -> String {
    let mut args = command.to_vec();
    args.push("--help");
    let (code, text) = common::prt(&args);
    assert_eq!(code, 0, "prt {}: {text}", args.join(" "));
    text
}

/// The `--flag` a help line starts, if it starts one: `  -o, --output <OUTPUT>`, `      --cube
/// <CUBE>  Cube face size ...`.
fn entry_flag(line: &str) -> Option<String> {
    let t = line.trim_start();
    if line.len() - t.len() >= ENTRY_INDENT {
        return None;
    }
    let long = match t.strip_prefix('-') {
        // `-o, --output`: a short flag, then its long name.
        Some(rest) if !rest.starts_with('-') => rest.split_once(", ")?.1,
        _ => t,
    };
    let name = long.strip_prefix("--")?;
    let end = name
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
        .unwrap_or(name.len());
    (end > 0).then(|| format!("--{}", &name[..end]))
}

/// The value of the first `[default: X]` on `line`.
fn default_in(line: &str) -> Option<String> {
    const OPEN: &str = "[default: ";
    let start = line.find(OPEN)? + OPEN.len();
    let len = line[start..].find(']')?;
    Some(
        line[start..start + len]
            .trim()
            .trim_matches('"')
            .to_string(),
    )
}

/// Every flag's `[default: X]` in a help text, in either of clap's layouts: on the flag's line,
/// or on a line of its own below the flag's description (long help).
fn parse_help_defaults(text: &str) -> Defaults {
    let mut defaults = Defaults::new();
    let mut flag: Option<String> = None;
    for line in text.lines() {
        let indent = line.len() - line.trim_start().len();
        if !line.trim().is_empty() && indent < ENTRY_INDENT {
            flag = entry_flag(line);
        }
        if let (Some(f), Some(d)) = (&flag, default_in(line)) {
            defaults.entry(f.clone()).or_insert(d);
        }
    }
    defaults
}

/// The defaults `prt COMMAND --help` gives.
fn help_defaults(command: &[&str]) -> Defaults {
    parse_help_defaults(&help(command))
}

/// The subcommands a help text lists under `Commands:` (`help` aside).
fn subcommands(text: &str) -> Vec<String> {
    let mut listed = Vec::new();
    let mut inside = false;
    for line in text.lines() {
        if line.trim_end() == "Commands:" {
            inside = true;
            continue;
        }
        if !inside {
            continue;
        }
        if line.trim().is_empty() || !line.starts_with(' ') {
            inside = false;
            continue;
        }
        let name = line.split_whitespace().next().unwrap_or("");
        if line.len() - line.trim_start().len() == 2 && name != "help" {
            listed.push(name.to_string());
        }
    }
    listed
}

/// Every command of `prt` (its words after `prt`, such as `volume bake`) and its defaults.
fn all_defaults() -> BTreeMap<String, Defaults> {
    let mut found = BTreeMap::new();
    let mut queue: Vec<Vec<String>> = vec![Vec::new()];
    while let Some(path) = queue.pop() {
        let words: Vec<&str> = path.iter().map(String::as_str).collect();
        let text = help(&words);
        let subs = subcommands(&text);
        if subs.is_empty() {
            found.insert(path.join(" "), parse_help_defaults(&text));
        }
        for sub in subs {
            let mut p = path.clone();
            p.push(sub);
            queue.push(p);
        }
    }
    assert!(
        ["bake", "relight", "view"]
            .iter()
            .all(|c| found.contains_key(*c)),
        "commands found: {:?}",
        found.keys().collect::<Vec<_>>()
    );
    found
}

/// A default the documentation states.
#[derive(Debug, PartialEq)]
struct Stated {
    /// The file and the 1-based line of the flag.
    at: String,
    flag: String,
    value: String,
    /// The command named last before it in its paragraph (`prt bake ...`, `- **bake**`).
    command: Option<String>,
}

/// Whether `word` is a long flag, `--name` or `--name=value`.
fn is_flag(word: &str) -> bool {
    let name = word.split('=').next().unwrap_or("");
    name.strip_prefix("--").is_some_and(|n| {
        n.starts_with(|c: char| c.is_ascii_lowercase())
            && n.chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
    })
}

/// The last flag among `words` and the value given with it, if any (`--device auto`).
fn last_flag(words: &[&str]) -> Option<(String, Option<String>)> {
    let i = words.iter().rposition(|w| is_flag(w))?;
    Some(match words[i].split_once('=') {
        Some((flag, value)) => (flag.to_string(), Some(value.to_string())),
        None => (
            words[i].to_string(),
            words
                .get(i + 1)
                .filter(|v| !v.starts_with(['-', '[']))
                .map(|v| v.to_string()),
        ),
    })
}

/// The longest of `commands` whose words start `words`.
fn command_named(words: &[&str], commands: &[String]) -> Option<String> {
    commands
        .iter()
        .filter(|c| {
            let cw: Vec<&str> = c.split(' ').collect();
            words.len() >= cw.len() && words[..cw.len()] == cw[..]
        })
        .max_by_key(|c| c.len())
        .cloned()
}

/// The default `tail` (the text after a flag, to the end of its sentence) states for it:
/// `(default 0.005)`, `, default 256`, `defaults to 4`, or after a flag given with its value
/// (`--device auto`), `, the default`. `None` for none, or for a default of the past (`0.01, the
/// default before`).
fn stated_value(tail: &str, in_span: Option<&str>) -> Option<String> {
    let lead = tail.trim_start().to_lowercase();
    if let Some(v) = in_span
        && [", the default", "(the default", "(default)"]
            .iter()
            .any(|p| lead.starts_with(p))
    {
        return Some(v.to_string());
    }
    let mut from = 0;
    while let Some(i) = tail[from..].find("default").map(|i| from + i) {
        from = i + "default".len();
        let word_end = tail[from..].strip_prefix('s').unwrap_or(&tail[from..]);
        if tail[..i].ends_with(|c: char| c.is_alphanumeric())
            || word_end.starts_with(|c: char| c.is_alphanumeric())
        {
            continue;
        }
        let before = tail[..i]
            .split_whitespace()
            .last()
            .unwrap_or("")
            .trim_matches(['(', ','])
            .to_lowercase();
        if NOT_A_STATEMENT.contains(&before.as_str()) {
            continue;
        }
        let mut rest = word_end.trim_start();
        rest = rest.strip_prefix(':').unwrap_or(rest).trim_start();
        for word in ["to ", "is "] {
            rest = rest.strip_prefix(word).unwrap_or(rest);
        }
        let len = rest
            .find(|c: char| !(c.is_alphanumeric() || ".,_/+-".contains(c)))
            .unwrap_or(rest.len());
        let value = rest[..len].trim_end_matches(['.', ',']);
        if !value.starts_with(|c: char| c.is_alphanumeric())
            || NOT_A_VALUE.contains(&value.to_lowercase().as_str())
        {
            continue;
        }
        let after: String = rest[value.len()..].chars().take(40).collect();
        if after.contains("before") || after.contains("of the day") {
            return None;
        }
        return Some(value.to_string());
    }
    None
}

/// What the markdown `text` (of the file `name`) says flags default to. A statement is a flag in
/// a code span (`` `--threshold` ``, `` `--edge-spp E` ``, `` `prt bake --bounces B` ``) followed
/// in its sentence by its default; it is credited to the command its paragraph or list item named
/// last (in a code span starting `prt`, or in bold as a list item's head). Fenced blocks are
/// skipped: their brackets list flags, not defaults.
fn stated_defaults(name: &str, text: &str, commands: &[String]) -> Vec<Stated> {
    enum Event {
        /// A paragraph, a list item or a heading starts: no command is named yet.
        Reset,
        Command(String),
        Flag {
            end: usize,
            flag: String,
            value: Option<String>,
        },
    }
    let mut fenced = false;
    let lines: Vec<&str> = text
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("```") {
                fenced = !fenced;
                return "";
            }
            if fenced { "" } else { l }
        })
        .collect();
    let doc = lines.join("\n");
    let mut resets = Vec::new();
    let (mut offset, mut after_blank) = (0, true);
    for l in &lines {
        let blank = l.trim().is_empty();
        let starts = l.starts_with('#')
            || l.starts_with("- ")
            || l.starts_with("* ")
            || (after_blank && !l.starts_with(' '));
        if !blank && starts {
            resets.push(offset);
        }
        after_blank = blank;
        offset += l.len() + 1;
    }
    let mut events: Vec<(usize, u8, Event)> =
        resets.iter().map(|&o| (o, 0, Event::Reset)).collect();
    let mut from = 0;
    while let Some(a) = doc[from..].find('`').map(|i| from + i) {
        let Some(b) = doc[a + 1..].find('`').map(|i| a + 1 + i) else {
            break;
        };
        from = b + 1;
        let span = doc[a + 1..b].trim();
        let words: Vec<&str> = span.split_whitespace().collect();
        if span.starts_with("prt ")
            && let Some(c) = command_named(&words[1..], commands)
        {
            events.push((a, 1, Event::Command(c)));
        }
        if (span.starts_with("--") || span.starts_with("prt "))
            && let Some((flag, value)) = last_flag(&words)
        {
            events.push((
                a,
                2,
                Event::Flag {
                    end: b,
                    flag,
                    value,
                },
            ));
        }
    }
    let mut from = 0;
    while let Some(a) = doc[from..].find("**").map(|i| from + i) {
        let Some(b) = doc[a + 2..].find("**").map(|i| a + 2 + i) else {
            break;
        };
        from = b + 2;
        let bold = doc[a + 2..b].replace('`', "");
        if let Some(c) = commands.iter().find(|c| **c == bold.trim()) {
            events.push((a, 1, Event::Command(c.clone())));
        }
    }
    events.sort_by_key(|(at, rank, _)| (*at, *rank));
    let flag_starts: Vec<usize> = events
        .iter()
        .filter(|(_, _, e)| matches!(e, Event::Flag { .. }))
        .map(|(at, _, _)| *at)
        .collect();
    let mut stated = Vec::new();
    let mut command: Option<String> = None;
    for (at, _, event) in &events {
        let (end, flag, value) = match event {
            Event::Reset => {
                command = None;
                continue;
            }
            Event::Command(c) => {
                command = Some(c.clone());
                continue;
            }
            Event::Flag { end, flag, value } => (*end, flag, value),
        };
        // The sentence after the flag, up to the next flag or paragraph.
        let mut stop = [
            flag_starts.iter().find(|&&f| f > *at),
            resets.iter().find(|&&r| r > end),
        ]
        .into_iter()
        .flatten()
        .copied()
        .fold(doc.len().min(end + 1 + STATEMENT_REACH), usize::min);
        while !doc.is_char_boundary(stop) {
            stop -= 1;
        }
        let mut tail = &doc[end + 1..stop];
        for sentence_end in [". ", ".\n", "; ", ";\n"] {
            if let Some(i) = tail.find(sentence_end) {
                tail = &tail[..i];
            }
        }
        if let Some(v) = stated_value(tail, value.as_deref()) {
            stated.push(Stated {
                at: format!("{name}:{}", doc[..*at].matches('\n').count() + 1),
                flag: flag.clone(),
                value: v,
                command: command.clone(),
            });
        }
    }
    stated
}

/// Whether two defaults are the same: as written, or as numbers with thousands separators
/// (`1,024` and `1024`).
fn same_value(a: &str, b: &str) -> bool {
    let number = |v: &str| -> Option<f64> {
        let grouped = v.split(',').skip(1).all(|g| {
            g.get(..3)
                .is_some_and(|d| d.chars().all(|c| c.is_ascii_digit()))
                && g.get(3..)
                    .is_some_and(|r| r.is_empty() || r.starts_with('.'))
        });
        grouped.then(|| v.replace(',', "").parse().ok()).flatten()
    };
    a == b || matches!((number(a), number(b)), (Some(x), Some(y)) if x == y)
}

/// Checks a stated default against the commands' help: the command its paragraph names, when
/// that command has the flag, else any command with it. `Ok(false)` when no command gives the
/// flag a default (nothing to hold it to).
fn check(stated: &Stated, defaults: &BTreeMap<String, Defaults>) -> Result<bool, String> {
    let given: Vec<(&String, &String)> = defaults
        .iter()
        .filter_map(|(c, d)| d.get(&stated.flag).map(|v| (c, v)))
        .collect();
    if given.is_empty() {
        return Ok(false);
    }
    let named = stated
        .command
        .as_ref()
        .and_then(|c| given.iter().find(|(g, _)| *g == c));
    let (agrees, held_to) = match named {
        Some((c, v)) => (
            same_value(&stated.value, v),
            format!("`prt {c} --help` says {v}"),
        ),
        None => (
            given.iter().any(|(_, v)| same_value(&stated.value, v)),
            given
                .iter()
                .map(|(c, v)| format!("`prt {c} --help` says {v}"))
                .collect::<Vec<_>>()
                .join(", "),
        ),
    };
    match agrees {
        true => Ok(true),
        false => Err(format!(
            "{}: `{}` is said to default to {}, but {held_to}",
            stated.at, stated.flag, stated.value
        )),
    }
}

#[test]
fn the_help_parser_reads_defaults_in_both_of_claps_layouts() {
    let text = concat!(
        "Usage: prt x [OPTIONS] <FILE>\n",
        "\n",
        "Arguments:\n",
        "  <FILE>  Transport file [default: not-a-flag]\n",
        "\n",
        "Options:\n",
        "      --cube <CUBE>          Cube face size [default: 32]\n",
        "  -o, --output <OUTPUT>      Output image\n",
        "      --seed <SEED>\n",
        "          Seed of every random choice [default: 1]\n",
        "      --terms <TERMS>\n",
        "          Kept wavelet terms K\n",
        "          \n",
        "          [default: 200]\n",
        "\n",
        "      --device <DEVICE>\n",
        "          Possible values:\n",
        "          - auto: A hardware GPU when one exists\n",
        "          - cpu:  The CPU kernels\n",
        "          \n",
        "          [default: auto]\n",
        "\n",
        "      --sh-order <SH_ORDER>\n",
        "          SH order (default: the baked order)\n",
        "      --grids <GRIDS>  Grids [default: \"32 64\"]\n",
        "  -h, --help  Print help\n",
    );
    let want: Defaults = [
        ("--cube", "32"),
        ("--seed", "1"),
        ("--terms", "200"),
        ("--device", "auto"),
        ("--grids", "32 64"),
    ]
    .into_iter()
    .map(|(f, v)| (f.to_string(), v.to_string()))
    .collect();
    assert_eq!(parse_help_defaults(text), want);
}

#[test]
fn the_doc_scan_finds_stated_defaults_and_skips_past_ones() {
    let commands: Vec<String> = ["bake", "relight", "volume bake"]
        .into_iter()
        .map(String::from)
        .collect();
    let text = concat!(
        "- **bake** drops terms under `--threshold` (default 0.01) times the norm.\n",
        "  At 0.01, the default before, `--threshold 0.01` kept less.\n",
        "\n",
        "`prt relight` takes `--terms` (default 200, at most 6 N²) and `--device auto`, the default.\n",
        "\n",
        "```\n",
        "prt bake [--threshold T (default 9)]\n",
        "```\n",
        "`--paths` P paths (default 1,024) and the default edge length of `--edge-length`.\n",
        "Orders (`prt volume bake --orders N`, default 4); `--cube` by default 32.\n",
    );
    let stated = |line: usize, flag: &str, value: &str, command: Option<&str>| Stated {
        at: format!("t.md:{line}"),
        flag: flag.into(),
        value: value.into(),
        command: command.map(String::from),
    };
    assert_eq!(
        stated_defaults("t.md", text, &commands),
        vec![
            stated(1, "--threshold", "0.01", Some("bake")),
            stated(4, "--terms", "200", Some("relight")),
            stated(4, "--device", "auto", Some("relight")),
            stated(9, "--paths", "1,024", None),
            stated(10, "--orders", "4", Some("volume bake")),
        ]
    );
    // The first is held to the bake's help, which says otherwise, and the message says where.
    let defaults: BTreeMap<String, Defaults> = [(
        "bake".to_string(),
        Defaults::from([("--threshold".to_string(), "0.005".to_string())]),
    )]
    .into();
    let e = check(&stated(1, "--threshold", "0.01", Some("bake")), &defaults).unwrap_err();
    assert!(
        e.contains("t.md:1") && e.contains("0.01") && e.contains("0.005"),
        "{e}"
    );
    assert!(same_value("1,024", "1024") && !same_value("1,2", "12"));
}

#[test]
fn every_default_the_docs_state_is_the_command_lines() {
    let defaults = all_defaults();
    let commands: Vec<String> = defaults.keys().cloned().collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut docs = vec![root.join("README.md")];
    if let Ok(entries) = std::fs::read_dir(root.join("docs/guide")) {
        let mut guides: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "md"))
            .collect();
        guides.sort();
        docs.extend(guides);
    }
    let mut wrong = Vec::new();
    let mut checked = Vec::new();
    for path in &docs {
        let text = std::fs::read_to_string(path).unwrap();
        let name = path
            .strip_prefix(root)
            .unwrap_or(path)
            .display()
            .to_string();
        for stated in stated_defaults(&name, &text, &commands) {
            match check(&stated, &defaults) {
                Ok(true) => checked.push(stated.flag),
                Ok(false) => {}
                Err(e) => wrong.push(e),
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "defaults the documentation states that the command line does not give:\n{}",
        wrong.join("\n")
    );
    // The scan sees the statements it is for.
    for flag in [
        "--threshold",
        "--sh-order",
        "--edge-spp",
        "--paths",
        "--terms",
    ] {
        assert!(
            checked.iter().any(|f| f == flag),
            "no default of {flag} found in README.md (checked: {checked:?})"
        );
    }
}

#[test]
fn prt_bake_and_the_demo_bake_with_one_set_of_defaults() {
    let bake = help_defaults(&["bake"]);
    let d = BakeSettings::default();
    for (flag, value) in [
        ("--cube", d.cube_n.to_string()),
        ("--sh-order", d.sh_order.to_string()),
        ("--threshold", d.threshold.to_string()),
        ("--spp", d.spp.to_string()),
        ("--edge-spp", d.edge_spp.to_string()),
        ("--edge-texel-samples", d.edge_texel_samples.to_string()),
        ("--paths", d.paths.to_string()),
    ] {
        assert_eq!(bake.get(flag), Some(&value), "`prt bake {flag}`");
    }
    let demo = demo_settings();
    assert_eq!(
        demo.sh_order, d.sh_order,
        "the demo's SH order is the bake's"
    );
    assert_eq!(
        demo.threshold, d.threshold,
        "the demo's threshold is the bake's"
    );
    let highest = DEMO_SH_ORDERS.iter().copied().max().unwrap_or(0);
    assert!(
        highest <= d.sh_order,
        "the demo shows SH order {highest}; the bake keeps {}",
        d.sh_order
    );
}

#[test]
fn the_viewer_opens_with_prt_relights_defaults() {
    let relight = help_defaults(&["relight"]);
    let k: usize = relight["--terms"].parse().unwrap();
    let (entries, light) = env_entries(&[SUN.to_string()]);
    let mut e = Engine::open(&common::viewer_transport_path(), entries).unwrap();
    assert!(
        e.transport.coeff_count() >= k,
        "the test bake must hold K = {k}"
    );
    let first = e.initial_state(light);
    assert_eq!(first.relight.terms, k, "the viewer's first K");
    assert_eq!(first.relight.method.to_string(), relight["--method"]);
    assert_eq!(first.relight.weighting.name(), relight["--weighting"]);
    // `prt relight --sh-order` defaults to the baked order.
    assert_eq!(first.relight.sh_order, common::VIEWER_SH_ORDER);
    let view = help_defaults(&["view"]);
    assert!(view.contains_key("--yaw"), "{view:?}");
    for (flag, value) in &view {
        if let Some(r) = relight.get(flag) {
            assert_eq!(value, r, "`prt view {flag}` against `prt relight {flag}`");
        }
    }
}

/// `prt view` of the lit test bake under [`SUN`] with `flags`: the screenshot's pixels without
/// its caption strip, and what the command printed.
fn view_image(dir: &Path, name: &str, flags: &[&str]) -> (Vec<u8>, String) {
    let png = dir.join(format!("{name}.png"));
    let file = common::lit_viewer_transport_path();
    let mut args = vec!["view", s(&file), "--env", SUN, "--screenshot", s(&png)];
    args.extend(flags);
    let (code, text) = common::prt(&args);
    assert_eq!(code, 0, "prt {}: {text}", args.join(" "));
    let img = image::open(&png).unwrap().to_rgb8();
    let strip = CAPTION_HEIGHT * img.width() as usize * 3;
    (img.as_raw()[strip..].to_vec(), text)
}

#[test]
fn a_screenshot_takes_the_relight_flags() {
    let dir = temp_dir("defaults-view-flags");
    let (default, _) = view_image(&dir, "default", &[]);
    let (k10, _) = view_image(&dir, "k10", &["--terms", "10"]);
    let (k200, _) = view_image(&dir, "k200", &["--terms", "200"]);
    assert!(
        k10 != k200,
        "--terms 10 and --terms 200 give the same image"
    );
    assert!(k200 == default, "K = 200 is the screenshot's first K");
    let (off, _) = view_image(&dir, "panel-off", &["--light", "panel=0"]);
    assert!(off != default, "--light panel=0 changes nothing");
    let (as_baked, _) = view_image(&dir, "panel-1", &["--light", "panel=1"]);
    assert!(
        as_baked == default,
        "--light panel=1 is the scene file's light"
    );
    let (moved, _) = view_image(&dir, "spot-1", &["--light", "spot@1"]);
    assert!(moved != default, "--light spot@1 changes nothing");
    let (turned, _) = view_image(&dir, "yaw", &["--yaw", "90"]);
    assert!(turned != default, "--yaw 90 changes nothing");
    let (sh, _) = view_image(&dir, "sh", &["--method", "sh", "--sh-order", "1"]);
    assert!(sh != default, "--method sh --sh-order 1 changes nothing");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn view_takes_and_refuses_the_light_flags_as_relight_does() {
    let dir = temp_dir("defaults-view-light-errors");
    let file = common::lit_viewer_transport_path();
    let png = dir.join("o.png");
    let error_line = |args: &[&str]| -> String {
        let (code, text) = common::prt(args);
        common::assert_clean_error(code, &text, &[]);
        text.lines()
            .find(|l| l.starts_with("error:"))
            .unwrap_or_else(|| panic!("no error line: {text}"))
            .to_string()
    };
    let bad = ["--light", "lamp=1"];
    let mut relight = vec!["relight", s(&file), "--env", SUN, "--device", "cpu", "-o"];
    relight.push(s(&png));
    relight.extend(bad);
    let mut view = vec!["view", s(&file), "--env", SUN, "--screenshot", s(&png)];
    view.extend(bad);
    let (a, b) = (error_line(&relight), error_line(&view));
    assert_eq!(a, b);
    assert!(b.contains("panel, spot"), "{b}");
    let mut view = vec!["view", s(&file), "--env", SUN, "--screenshot", s(&png)];
    view.extend(["--light", "panel=5000"]);
    let e = error_line(&view);
    assert!(e.contains("`panel`") && e.contains("1024"), "{e}");
    // Without --screenshot, the window refuses them before it opens.
    for flags in [
        &["--light", "panel=0"][..],
        &["--yaw", "30"],
        &["--terms", "10"],
    ] {
        let mut args = vec!["view", s(&file)];
        args.extend(flags);
        let e = error_line(&args);
        assert!(e.contains("--screenshot"), "{flags:?}: {e}");
    }
    let text = help(&["view"]);
    for flag in [
        "--light <NAME=VALUE>",
        "--yaw",
        "--pitch",
        "--method",
        "--terms",
        "--weighting",
        "--sh-order",
    ] {
        assert!(
            text.contains(flag),
            "`prt view --help` lacks {flag}: {text}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The figure after `label` in `text`, checked to be a percent with two decimals (`53.29%`).
fn percent_after(text: &str, label: &str) -> String {
    let at = text
        .find(label)
        .unwrap_or_else(|| panic!("no `{label}` in: {text}"))
        + label.len();
    let figure: String = text[at..]
        .chars()
        .take_while(|c| !c.is_whitespace() && *c != ',')
        .collect();
    let digits = figure.strip_suffix('%').unwrap_or("");
    let (whole, decimals) = digits.split_once('.').unwrap_or(("", ""));
    assert!(
        !whole.is_empty()
            && whole.chars().all(|c| c.is_ascii_digit())
            && decimals.len() == 2
            && decimals.chars().all(|c| c.is_ascii_digit()),
        "`{figure}` is not a percent with two decimals: {text}"
    );
    figure
}

#[test]
fn a_screenshot_prints_relative_errors_in_percent() {
    let dir = temp_dir("defaults-view-percent");
    let (_, text) = view_image(&dir, "k10", &["--terms", "10"]);
    let shown = percent_after(&text, "relative L2 vs full ");
    let (entries, light) = env_entries(&[SUN.to_string()]);
    let mut e = Engine::open(&common::lit_viewer_transport_path(), entries).unwrap();
    let mut state = e.initial_state(light);
    state.relight.terms = 10;
    let pane = e.render(&state).unwrap().panes.remove(0).linear;
    assert!(pane.rel_l2 > 0.0, "10 terms leave an error");
    assert_eq!(shown, format!("{:.2}%", 100.0 * pane.rel_l2), "{text}");
    assert_eq!(pane.rel_l2_percent(), shown);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Lets the window's worker finish and draws its answers (as `tests/viewer_ui.rs` does).
fn settle(h: &mut Harness<'static, ViewerApp>) {
    h.run_ok();
    for _ in 0..20 {
        assert!(
            h.state().wait_idle(Duration::from_secs(120)),
            "the worker did not finish"
        );
        h.step();
        if !h.state().busy() {
            break;
        }
    }
    h.run();
}

#[test]
fn the_window_opens_at_relights_k_and_shows_errors_in_percent() {
    // The harness renders with wgpu: it needs an adapter (a software one will do).
    if common::gpu_or_skip("the_window_opens_at_relights_k_and_shows_errors_in_percent").is_none() {
        return;
    }
    let k: usize = help_defaults(&["relight"])["--terms"].parse().unwrap();
    let app = ViewerApp::new(&common::viewer_transport_path(), &[SUN.to_string()]);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1000.0, 700.0))
        .wgpu()
        .build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app);
    settle(&mut h);
    assert_eq!(h.state().state.relight.terms, k, "the window's first K");
    let shown: Vec<String> = h
        .query_all_by_label_contains("L2 vs full")
        .map(|n| {
            n.value()
                .or_else(|| n.accesskit_node().label())
                .unwrap_or_default()
        })
        .collect();
    assert!(!shown.is_empty(), "the panel shows no error");
    for text in &shown {
        percent_after(text, "L2 vs full ");
    }
}
