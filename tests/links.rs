//! Every relative link and image of README.md, CHANGELOG.md, ARCHITECTURE.md and docs/guide/*.md
//! leads to a file or folder that exists, and every `#anchor` into a Markdown file (the same file
//! included) names one of its headings, slugged as GitHub slugs them. Links inside fenced code
//! blocks are not links and are skipped; http(s) and mailto links are not followed.

use std::collections::{BTreeMap, HashSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The documents checked: the three at the crate's root and every page of the guide.
fn documents(root: &Path) -> Vec<PathBuf> {
    let mut docs: Vec<PathBuf> = ["README.md", "CHANGELOG.md", "ARCHITECTURE.md"]
        .iter()
        .map(|f| root.join(f))
        .collect();
    let guide = root.join("docs/guide");
    let mut pages: Vec<PathBuf> = fs::read_dir(&guide)
        .unwrap_or_else(|e| panic!("{}: {e}", guide.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.sort();
    docs.extend(pages);
    docs
}

/// The lines of `text` outside fenced code blocks (``` or ~~~), with their 1-based numbers.
fn prose_lines(text: &str) -> Vec<(usize, &str)> {
    let mut fence: Option<&str> = None;
    let mut lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let mark = ["```", "~~~"].into_iter().find(|m| t.starts_with(*m));
        match (mark, fence) {
            (Some(m), None) => fence = Some(m),
            (Some(m), Some(f)) if m == f => fence = None,
            (None, None) => lines.push((i + 1, line)),
            _ => {}
        }
    }
    lines
}

/// GitHub's anchor for a heading: lower case, every character but letters, digits, spaces,
/// hyphens and underscores dropped, spaces made hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown text's headings (`#` to `######`, outside fenced blocks); a heading
/// met again takes `-1`, `-2`, ... after its anchor, as on GitHub.
fn anchors(text: &str) -> HashSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut found = HashSet::new();
    for (_, line) in prose_lines(text) {
        let hashes = line.len() - line.trim_start_matches('#').len();
        let rest = &line[hashes..];
        if !(1..=6).contains(&hashes) || !(rest.is_empty() || rest.starts_with([' ', '\t'])) {
            continue;
        }
        // A closing run of `#` counts only after a space: `## C#` keeps its `#`.
        let title = rest.trim();
        let open = title.trim_end_matches('#');
        let title = if open.is_empty() || open.ends_with([' ', '\t']) {
            open.trim_end()
        } else {
            title
        };
        let base = slug(title);
        let n = seen.entry(base.clone()).or_insert(0);
        found.insert(if *n == 0 { base } else { format!("{base}-{n}") });
        *n += 1;
    }
    found
}

/// The targets of the links and images on a line: what follows each `](` up to its `)`, without
/// a title (`(path "title")`) or angle brackets (`(<path>)`).
fn targets(line: &str) -> Vec<&str> {
    let mut found = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let Some(j) = after.find(')') else {
            break;
        };
        let inside = after[..j].trim();
        let target = match inside.strip_prefix('<') {
            Some(bracketed) => bracketed.split('>').next().unwrap_or(""),
            None => inside.split_whitespace().next().unwrap_or(""),
        };
        if !target.is_empty() {
            found.push(target);
        }
        rest = &after[j + 1..];
    }
    found
}

/// Whether a target leaves the repository: a web or mail address.
fn is_external(target: &str) -> bool {
    let lower = target.to_ascii_lowercase();
    ["http:", "https:", "mailto:"]
        .iter()
        .any(|scheme| lower.starts_with(*scheme))
}

/// `%XX` escapes decoded (`%20` is a space); a `%` not followed by two hex digits stays as it is.
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escaped = bytes
            .get(i + 1..i + 3)
            .filter(|h| h.iter().all(u8::is_ascii_hexdigit))
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], escaped) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Why `target`, a relative link of the document `doc`, leads nowhere; `headings` keeps the
/// anchors of every Markdown file read so far.
fn check(
    doc: &Path,
    target: &str,
    headings: &mut BTreeMap<PathBuf, HashSet<String>>,
) -> Result<(), String> {
    let (path, anchor) = match target.split_once('#') {
        Some((p, a)) => (p, Some(a)),
        None => (target, None),
    };
    let dest = if path.is_empty() {
        doc.to_path_buf()
    } else {
        doc.parent()
            .unwrap_or(Path::new("."))
            .join(percent_decode(path))
    };
    if !dest.exists() {
        return Err(format!("no such file or folder: {}", dest.display()));
    }
    let Some(anchor) = anchor.filter(|a| !a.is_empty()) else {
        return Ok(());
    };
    if !(dest.is_file() && dest.extension().is_some_and(|x| x == "md")) {
        return Ok(());
    }
    let key = dest.canonicalize().unwrap_or_else(|_| dest.clone());
    let known = headings.entry(key).or_insert_with(|| {
        let text = fs::read_to_string(&dest).unwrap_or_else(|e| panic!("{}: {e}", dest.display()));
        anchors(&text)
    });
    let anchor = percent_decode(anchor);
    if known.contains(&anchor) {
        Ok(())
    } else {
        Err(format!(
            "no heading #{anchor} in {}",
            dest.file_name().unwrap_or_default().to_string_lossy()
        ))
    }
}

#[test]
fn every_relative_link_of_the_documentation_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut headings = BTreeMap::new();
    let mut broken = Vec::new();
    let mut checked = 0;
    for doc in documents(root) {
        let text = fs::read_to_string(&doc).unwrap_or_else(|e| panic!("{}: {e}", doc.display()));
        let name = doc.strip_prefix(root).unwrap_or(&doc).display().to_string();
        for (n, line) in prose_lines(&text) {
            for target in targets(line).into_iter().filter(|t| !is_external(t)) {
                checked += 1;
                if let Err(why) = check(&doc, target, &mut headings) {
                    broken.push(format!("{name}:{n}: ({target}) {why}"));
                }
            }
        }
    }
    assert!(
        broken.is_empty(),
        "{} broken link(s) of {checked}:\n{}",
        broken.len(),
        broken.join("\n")
    );
    assert!(checked > 0, "no relative links found");
}

#[test]
fn the_checker_reads_links_headings_and_fences_as_github_does() {
    assert_eq!(slug("At the paper's scale"), "at-the-papers-scale");
    assert_eq!(slug("The `[medium]` table"), "the-medium-table");
    assert_eq!(slug("Kernel speed"), "kernel-speed");
    let text = concat!(
        "# Title\n",
        "## Part ##\n",
        "## Part\n",
        "### C#\n",
        "```sh\n",
        "# not a heading\n",
        "[not](a-link.md)\n",
        "```\n",
        "#hashtag\n",
        "[a](x.md#part) and ![b](<my pic.png> \"title\") and [c](https://example.org/)\n",
    );
    let found = anchors(text);
    for a in ["title", "part", "part-1", "c"] {
        assert!(found.contains(a), "{a} in {found:?}");
    }
    assert!(!found.contains("not-a-heading") && !found.contains("hashtag"));
    let lines = prose_lines(text);
    assert!(lines.iter().all(|(_, l)| !l.contains("a-link")));
    let (n, last) = *lines.last().unwrap();
    assert_eq!(n, 10);
    assert_eq!(
        targets(last),
        ["x.md#part", "my pic.png", "https://example.org/"]
    );
    assert!(is_external("https://example.org/") && !is_external("docs/guide/README.md"));
    assert_eq!(percent_decode("my%20pic.png"), "my pic.png");
    assert_eq!(percent_decode("100%"), "100%");
}
