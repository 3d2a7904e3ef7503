//! Files in and out, the same way for every loader and every command.
//!
//! Inputs are read only from regular files whose size is known and checked against a limit
//! before anything is read, so a device (`/dev/zero`), a FIFO or a directory given as a scene,
//! mesh or grid is an error at once rather than a read until memory runs out.
//!
//! Outputs are written to a temporary file this program names beside the output,
//! `NAME.partial-HOST-PID.EXT` (the real extension kept last, for writers that go by it), then
//! renamed into place: an interrupted write never leaves a half file under the final name. The
//! temporary file is removed when the write fails, and a later write to the same output removes
//! those a killed run of this host left behind. Files get the permissions the umask gives. A
//! command checks its outputs first ([`check_output`]): the extension must be the format it
//! writes, and an output must not be one of its inputs.

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{PrtError, Result};

/// Largest scene file (TOML text).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ mesh file.
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Opens `path` for reading if it is a regular file of at most `max_bytes`, checked before
/// anything is read; returns the file and its size. `what` names the kind of file in messages
/// ("scene", "mesh").
pub fn open_regular(path: &Path, max_bytes: u64, what: &str) -> Result<(std::fs::File, u64)> {
    // Checked before the open too: opening a FIFO for reading waits for a writer.
    let before = std::fs::metadata(path).map_err(|e| PrtError::io(path, e))?;
    if !before.is_file() {
        return Err(not_regular(path, &before, what));
    }
    let file = std::fs::File::open(path).map_err(|e| PrtError::io(path, e))?;
    // The metadata of the open file, not of the path: what is read is what was checked.
    let meta = file.metadata().map_err(|e| PrtError::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path, &meta, what));
    }
    let len = meta.len();
    if len > max_bytes {
        return Err(PrtError::file(
            path,
            format!("{len} bytes, more than the {max_bytes} allowed for the {what}"),
        ));
    }
    Ok((file, len))
}

fn not_regular(path: &Path, meta: &std::fs::Metadata, what: &str) -> PrtError {
    let kind = if meta.is_dir() {
        "a directory"
    } else {
        "not a regular file (a device, pipe or socket)"
    };
    PrtError::file(path, format!("{kind}: the {what} must be a regular file"))
}

/// Reads a whole regular file of at most `max_bytes` (see [`open_regular`]). A file that grows
/// while it is read is cut off at the limit and refused.
pub fn read_regular(path: &Path, max_bytes: u64, what: &str) -> Result<Vec<u8>> {
    let (file, len) = open_regular(path, max_bytes, what)?;
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(len as usize)
        .map_err(|_| PrtError::file(path, format!("{len} bytes do not fit in memory")))?;
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| PrtError::io(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(PrtError::file(
            path,
            format!("grew past the {max_bytes} bytes allowed for the {what} while it was read"),
        ));
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text.
pub fn read_regular_text(path: &Path, max_bytes: u64, what: &str) -> Result<String> {
    String::from_utf8(read_regular(path, max_bytes, what)?).map_err(|e| {
        PrtError::file(
            path,
            format!(
                "not UTF-8 text (byte {}): the {what} must be text",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Checks an output before a command does any work: its extension is one of `extensions`
/// (compared without case; `what` names the format in the message), its folder exists, and it
/// is none of `inputs` (the same file, however it is named: links and `..` included).
pub fn check_output(
    output: &Path,
    extensions: &[&str],
    what: &str,
    inputs: &[&Path],
) -> Result<()> {
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !extensions.iter().any(|e| Some(*e) == ext.as_deref()) {
        let list = extensions
            .iter()
            .map(|e| format!(".{e}"))
            .collect::<Vec<_>>()
            .join(" or ");
        return Err(PrtError::file(
            output,
            format!("this command writes {what}: name it {list}"),
        ));
    }
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        let message = if dir.exists() {
            format!("{} is not a folder", dir.display())
        } else {
            format!("the folder {} does not exist", dir.display())
        };
        return Err(PrtError::file(output, message));
    }
    for input in inputs {
        if same_file(output, input) {
            return Err(PrtError::file(
                output,
                format!(
                    "this is also an input ({}): writing it would replace the input; choose \
                     another output",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Whether `a` and `b` name one existing file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

/// The marker between an output's name and the temporary file's owner.
const PARTIAL: &str = ".partial-";

/// This host's name as it goes into temporary file names (letters, digits and `-`).
fn host_tag() -> String {
    let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_default();
    let tag: String = raw
        .trim()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .take(64)
        .collect();
    if tag.is_empty() { "host".into() } else { tag }
}

/// The temporary file a write of `path` by process `pid` of this host goes through.
pub fn partial_path(path: &Path, pid: u32) -> PathBuf {
    partial_path_of(path, &host_tag(), pid, None)
}

/// A temporary file that holds part `tag` of a write of `path` by process `pid` of this host
/// while it is made (`NAME.partial-HOST-PID.spill-TAG.EXT`); [`remove_stale_partials`] removes
/// those a killed run left behind.
pub fn spill_path(path: &Path, pid: u32, tag: &str) -> PathBuf {
    partial_path_of(path, &host_tag(), pid, Some(tag))
}

/// [`partial_path`] for the host named `host`, with `.spill-TAG` for [`spill_path`].
fn partial_path_of(path: &Path, host: &str, pid: u32, tag: Option<&str>) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(format!("{PARTIAL}{host}-{pid}"));
    if let Some(tag) = tag {
        name.push(format!(".spill-{tag}"));
    }
    if let Some(ext) = path.extension() {
        name.push(".");
        name.push(ext);
    }
    path.with_file_name(name)
}

/// Whether process `pid` of this host is still running, when that can be known.
fn process_alive(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return None;
    }
    Some(proc.join(pid.to_string()).exists())
}

/// Removes the temporary files of earlier writes of `path` by processes of this host that are
/// gone (killed during the write). Files of running processes and of other hosts stay.
pub fn remove_stale_partials(path: &Path) {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = format!("{name}{PARTIAL}{}-", host_tag());
    let suffix = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| format!(".{e}"))
        .unwrap_or_default();
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
            continue;
        };
        // `PID`, or `PID.spill-TAG` ([`spill_path`]).
        let Some(pid) = rest
            .strip_suffix(&suffix)
            .and_then(|p| p.split('.').next())
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && process_alive(pid) == Some(false) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Runs `write` on a temporary path beside `path` (see the module docs), then renames it into
/// place, so an interrupted write never leaves a half file under the final name. Errors name
/// `path`, not the temporary file.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    remove_stale_partials(path);
    let tmp = partial_path(path, std::process::id());
    if let Err(e) = write(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.renaming(&tmp, path));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        PrtError::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_names_keep_the_extension_and_parse_back() {
        let p = partial_path_of(Path::new("dir/out.prt"), "node-1", 42, None);
        assert_eq!(p, Path::new("dir/out.prt.partial-node-1-42.prt"));
        let p = partial_path_of(Path::new("dir/out.prt"), "node-1", 42, Some("sh"));
        assert_eq!(p, Path::new("dir/out.prt.partial-node-1-42.spill-sh.prt"));
        assert_eq!(p.extension().and_then(|e| e.to_str()), Some("prt"));
        let p = partial_path_of(Path::new("noext"), "h", 7, None);
        assert_eq!(p, Path::new("noext.partial-h-7"));
    }

    #[test]
    fn spills_of_a_killed_run_are_removed_and_those_of_a_running_one_kept() {
        let dir = std::env::temp_dir().join(format!("prt-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("out.prt");
        let spill = |pid: u32| spill_path(&out, pid, "entry_value");
        // No process has an id this large; process 1 always runs.
        let (dead, alive) = (spill(4_000_000_000), spill(1));
        let other = dir.join("out.prt.notes.txt");
        for p in [&dead, &alive, &other] {
            std::fs::write(p, b"x").unwrap();
        }
        remove_stale_partials(&out);
        assert!(!dead.exists());
        assert!(alive.exists() && other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
