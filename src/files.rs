//! Files in and out, the same way for every loader and every command.
//!
//! Inputs are read only from regular files whose size is known and checked against a limit
//! before anything is read, so a device (`/dev/zero`), a FIFO or a directory given as a scene,
//! mesh or grid is an error at once rather than a read until memory runs out.
//!
//! Outputs are written to a temporary file beside the output,
//! `NAME.partial-HOST-SPACE-PID-RANDOM.EXT` (the real extension kept last, for writers that go
//! by it), then renamed into place: an interrupted write never leaves a half file under the
//! final name. SPACE tells apart machines and PID namespaces that share a host name, and RANDOM
//! is 64 bits nobody can predict. The file is created exclusively (`O_CREAT | O_EXCL`): a file or
//! a symbolic link planted at the name is never opened or followed, and another name is tried.
//! The temporary file is removed when the write fails or the program is interrupted (SIGINT,
//! SIGTERM), and a later write to the same output removes those a killed run of this host and
//! namespace left behind. Spill files (parts of a large output written before it) are removed
//! from the folder as soon as they are opened, so nothing is left of them whatever ends the
//! process. Files get the permissions the umask gives. A command checks its outputs first
//! ([`check_output`]): the extension must be the format it writes, the folder must exist and be
//! writable, the output must not be a folder, and it must not be one of its inputs.

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
    // A file whose content is not its size (`/proc`'s and `/sys`'s give 0) escapes the limit's
    // check: it is no regular input.
    if bytes.len() as u64 != len {
        return Err(PrtError::file(
            path,
            format!(
                "held {} bytes where its size said {len}: the {what} must be a regular file \
                 that nothing writes while it is read",
                bytes.len()
            ),
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
    let dir = folder_of(output);
    if !dir.is_dir() {
        let message = if dir.exists() {
            format!("{} is not a folder", dir.display())
        } else {
            format!("the folder {} does not exist", dir.display())
        };
        return Err(PrtError::file(output, message));
    }
    if output.is_dir() {
        return Err(PrtError::file(
            output,
            "is a folder: name a file to write (a file inside it, say)",
        ));
    }
    check_writable(output)?;
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

/// Checks that a temporary file can be created beside `output`, as a write of it will: a
/// read-only folder or a full disk is found before any work.
fn check_writable(output: &Path) -> Result<()> {
    let (tmp, file) = create_partial(output, Some("probe"))?;
    drop(file);
    let _ = std::fs::remove_file(&tmp);
    forget_partial(&tmp);
    Ok(())
}

/// Creates folder `dir` with its parents where missing; the error names it.
pub fn create_folder(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| PrtError::io(dir, e))
}

/// Checks a folder a command writes several files into, before any work: it is created when
/// missing (with its parents), must be a folder, and must be writable.
pub fn check_output_folder(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(PrtError::file(
            dir,
            "is a file: name a folder for the outputs",
        ));
    }
    create_folder(dir)?;
    check_writable(&dir.join("probe")).map_err(|e| match e {
        PrtError::File { message, .. } => PrtError::file(dir, message),
        e => e,
    })
}

/// A file bundled into the binary: its path under the repository's `assets/`, and its bytes.
/// The environment maps that every `--env` takes by name and the demo's scenes and meshes are
/// bundled so, each by the crate's `bundled!` macro.
#[derive(Clone, Copy)]
pub struct Bundled {
    /// Path under `assets/`, such as `scenes/demo.toml` or `envmaps/blender_sunrise.exr`.
    pub path: &'static str,
    /// The file's content.
    pub bytes: &'static [u8],
}

impl Bundled {
    /// The file's name without its folder and extension, such as `blender_sunrise`.
    pub fn stem(&self) -> &'static str {
        Path::new(self.path)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or(self.path)
    }
}

impl std::fmt::Debug for Bundled {
    /// The path and the size, not the bytes.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Bundled({}, {} bytes)", self.path, self.bytes.len())
    }
}

/// The [`Bundled`] file at this path under `assets/`: `bundled!("scenes/demo.toml")`.
macro_rules! bundled {
    ($path:expr) => {
        $crate::files::Bundled {
            path: $path,
            bytes: include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/", $path)),
        }
    };
}
pub(crate) use bundled;

/// The size of the file at `path` in bytes, or an error naming it.
pub fn file_len(path: &Path) -> Result<u64> {
    Ok(std::fs::metadata(path)
        .map_err(|e| PrtError::io(path, e))?
        .len())
}

/// `text` with its control characters escaped (`\u{1b}`), so a string read from a file can be
/// printed without driving the terminal.
pub fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// Bytes this process can still allocate, when that can be known: the memory the system has
/// available (`MemAvailable`), and under an address-space limit (`ulimit -v`) what is left of
/// it. Large outputs are estimated against it before any work.
pub fn memory_headroom() -> Option<u64> {
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let available = meminfo
        .as_deref()
        .and_then(|t| field(t, "MemAvailable:"))
        .map(|kib| kib * 1024);
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let limit = limits
        .as_deref()
        .and_then(|t| field(t, "Max address space"))
        .and_then(|bytes| {
            let status = std::fs::read_to_string("/proc/self/status").ok()?;
            let used = field(&status, "VmSize:")? * 1024;
            Some(bytes.saturating_sub(used))
        });
    match (available, limit) {
        (Some(a), Some(l)) => Some(a.min(l)),
        (a, l) => a.or(l),
    }
}

/// Refuses an allocation of `bytes` that this process cannot have (see [`memory_headroom`]),
/// before any work: `what` names the thing in the message ("a 16384 x 16384 reference image"),
/// `field` the flag or file field that sets its size. Where the headroom cannot be known, only
/// sizes past the address space are refused.
pub fn check_memory(field: &str, what: &str, bytes: u64) -> Result<()> {
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    let refuse = |have: String| {
        Err(PrtError::invalid(
            field,
            format!(
                "{what} needs about {:.1} GiB, and this process can have {have}: make it smaller",
                gib(bytes)
            ),
        ))
    };
    if bytes > isize::MAX as u64 {
        return refuse("far less".into());
    }
    match memory_headroom() {
        Some(have) if bytes > have => refuse(format!("{:.1} GiB", gib(have))),
        _ => Ok(()),
    }
}

/// A vector of `n` copies of `value`, its memory checked with [`check_memory`] and reserved
/// fallibly: an error naming `field`, never an abort.
pub fn try_filled<T: Clone>(field: &str, what: &str, n: usize, value: T) -> Result<Vec<T>> {
    let bytes = (n as u64).saturating_mul(std::mem::size_of::<T>() as u64);
    check_memory(field, what, bytes)?;
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        PrtError::invalid(
            field,
            format!(
                "{what} needs about {:.1} GiB, which this process cannot have: make it smaller",
                bytes as f64 / (1u64 << 30) as f64
            ),
        )
    })?;
    v.resize(n, value);
    Ok(v)
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
/// Fresh names tried for a temporary file before giving up: a name is taken only when a file of
/// that name exists already, which with 64 random bits means one was planted there.
const CREATE_TRIES: usize = 16;

/// Who writes a temporary file: this host's name (letters, digits and `-`) and 8 hex digits of
/// a hash of what tells apart the machines and the PID namespaces that share the name (the
/// kernel's boot id and the PID namespace). Two containers with one host name, whose processes
/// may have the same PID, so never take each other's temporary files for their own.
fn owner_tag() -> String {
    let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_default();
    let mut tag: String = raw
        .trim()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .take(64)
        .collect();
    if tag.is_empty() {
        tag = "host".into();
    }
    let boot = std::fs::read_to_string("/proc/sys/kernel/random/boot_id").unwrap_or_default();
    let pid_ns = std::fs::read_link("/proc/self/ns/pid")
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    // FNV-1a: stable across builds and processes, which a keyed hash is not.
    let space = format!("{}|{pid_ns}", boot.trim())
        .bytes()
        .fold(0x811c_9dc5u32, |h, b| {
            (h ^ b as u32).wrapping_mul(0x0100_0193)
        });
    format!("{tag}-{space:08x}")
}

/// 16 hex digits nobody else can predict: std's `RandomState` keys come from the operating
/// system's random source, and a counter makes each call differ.
fn random_tag() -> String {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(CALLS.fetch_add(1, Ordering::Relaxed));
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0),
    );
    format!("{:016x}", h.finish())
}

/// The temporary file `NAME.partial-OWNER-PID-RANDOM[.PART].EXT` of a write of `path`: `part`
/// is `spill-TENSOR` for a spill file, none for the output's own temporary file.
fn partial_path_of(
    path: &Path,
    owner: &str,
    pid: u32,
    random: &str,
    part: Option<&str>,
) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(format!("{PARTIAL}{owner}-{pid}-{random}"));
    if let Some(part) = part {
        name.push(format!(".{part}"));
    }
    if let Some(ext) = path.extension() {
        name.push(".");
        name.push(ext);
    }
    path.with_file_name(name)
}

/// Temporary files this process has created and not yet renamed or removed, for
/// [`remove_partials_in_progress`].
static IN_PROGRESS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn in_progress() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    IN_PROGRESS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn forget_partial(path: &Path) {
    in_progress().retain(|p| p != path);
}

/// Removes every temporary file this process is writing: for a handler of SIGINT or SIGTERM,
/// just before the process exits. Spill files need none (see [`create_partial`]).
pub fn remove_partials_in_progress() {
    for p in in_progress().drain(..) {
        let _ = std::fs::remove_file(p);
    }
}

/// A name a temporary file of a write of `path` by process `pid` of this host and PID namespace
/// may have (with a fresh random part): what a run killed while writing leaves behind.
pub fn partial_path(path: &Path, pid: u32) -> PathBuf {
    partial_path_of(path, &owner_tag(), pid, &random_tag(), None)
}

/// Creates a temporary file beside the output `path` (see the module docs), exclusively: the
/// open fails rather than follow a link or reuse a file planted at its name, and another fresh
/// name is tried then. `part` marks a spill file (`spill-TENSOR`). Errors name the output.
pub fn create_partial(path: &Path, part: Option<&str>) -> Result<(PathBuf, std::fs::File)> {
    create_partial_as(
        path,
        &owner_tag(),
        std::process::id(),
        part,
        &mut random_tag,
    )
}

/// [`create_partial`] with the owner, the process id and the random parts given.
fn create_partial_as(
    path: &Path,
    owner: &str,
    pid: u32,
    part: Option<&str>,
    random: &mut dyn FnMut() -> String,
) -> Result<(PathBuf, std::fs::File)> {
    let dir = folder_of(path);
    for _ in 0..CREATE_TRIES {
        let tmp = partial_path_of(path, owner, pid, &random(), part);
        // O_CREAT | O_EXCL: an existing name fails, a symbolic link included (it is not
        // followed, dangling or not).
        match std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(file) => {
                in_progress().push(tmp.clone());
                return Ok((tmp, file));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => {
                return Err(PrtError::file(
                    path,
                    format!("cannot create a temporary file in {}: {e}", dir.display()),
                ));
            }
        }
    }
    Err(PrtError::file(
        path,
        format!(
            "cannot create a temporary file in {}: {CREATE_TRIES} fresh random names were all \
             taken (files planted in the folder?)",
            dir.display()
        ),
    ))
}

/// The folder of `path` (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A spill file: created as [`create_partial`] does, then, where the platform allows, removed
/// from its folder at once while this process keeps it open, so that no end of the process
/// (a crash, SIGKILL) leaves it behind. The path is returned for the platforms that keep it.
pub fn create_spill(path: &Path, tensor: &str) -> Result<(Option<PathBuf>, std::fs::File)> {
    let (tmp, file) = create_partial(path, Some(&format!("spill-{tensor}")))?;
    forget_partial(&tmp);
    if cfg!(unix) && std::fs::remove_file(&tmp).is_ok() {
        return Ok((None, file));
    }
    Ok((Some(tmp), file))
}

/// Whether process `pid` of this host is still running, when that can be known.
fn process_alive(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return None;
    }
    Some(proc.join(pid.to_string()).exists())
}

/// Removes the temporary files of earlier writes of `path` by processes of this host and PID
/// namespace that are gone (killed during the write). Files of running processes, of other
/// hosts and of other containers stay; a link is removed as a link, never followed.
pub fn remove_stale_partials(path: &Path) {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(folder_of(path)) else {
        return;
    };
    let prefix = format!("{name}{PARTIAL}{}-", owner_tag());
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
            continue;
        };
        // `PID-RANDOM...`.
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        // The entry's own type, not its target's.
        let plain = entry
            .file_type()
            .is_ok_and(|t| t.is_file() || t.is_symlink());
        if plain && pid != std::process::id() && process_alive(pid) == Some(false) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The inputs of this process's command that no output may replace, by device and inode.
static GUARDED_INPUTS: std::sync::Mutex<Vec<(PathBuf, (u64, u64))>> =
    std::sync::Mutex::new(Vec::new());

/// A file's device and inode, when it exists.
fn file_id(path: &Path) -> Option<(u64, u64)> {
    let meta = std::fs::metadata(path).ok()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some((meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        let canonical = std::fs::canonicalize(path).ok()?;
        let mut h = std::collections::hash_map::DefaultHasher::new();
        std::hash::Hash::hash(&canonical, &mut h);
        Some((0, std::hash::Hasher::finish(&h)))
    }
}

/// Marks `inputs` as files no output of this process may replace: a command that writes many
/// files into a folder (a study's report, its plots) calls it with what it read, and
/// [`write_atomically`] then refuses an output that is one of them, however it is named.
pub fn guard_inputs<P: AsRef<Path>>(inputs: &[P]) {
    let mut guarded = GUARDED_INPUTS.lock().unwrap_or_else(|e| e.into_inner());
    for p in inputs {
        if let Some(id) = file_id(p.as_ref()) {
            guarded.push((p.as_ref().to_path_buf(), id));
        }
    }
}

/// An error when writing `output` would replace a guarded input ([`guard_inputs`]).
fn check_not_guarded(output: &Path) -> Result<()> {
    let Some(id) = file_id(output) else {
        return Ok(());
    };
    let guarded = GUARDED_INPUTS.lock().unwrap_or_else(|e| e.into_inner());
    match guarded.iter().find(|(_, g)| *g == id) {
        Some((input, _)) => Err(PrtError::file(
            output,
            format!(
                "this is also an input ({}): writing it would replace the input; choose \
                 another output folder",
                input.display()
            ),
        )),
        None => Ok(()),
    }
}

/// Checks, before any work, that none of the files `names` a command will write into `dir` is
/// a guarded input ([`guard_inputs`]): the check a single output gets from [`check_output`].
pub fn check_folder_outputs(dir: &Path, names: &[&str]) -> Result<()> {
    names
        .iter()
        .try_for_each(|name| check_not_guarded(&dir.join(name)))
}

/// Runs `write` on a temporary file created beside `path` (see the module docs and
/// [`create_partial`]), then renames it into place, so an interrupted write never leaves a half
/// file under the final name. `write` gets the open file, and names `path` in its errors; the
/// temporary file is removed when it fails.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(std::fs::File) -> Result<()>,
) -> Result<()> {
    check_not_guarded(path)?;
    remove_stale_partials(path);
    let (tmp, file) = create_partial(path, None)?;
    finish_partial(path, &tmp, write(file))
}

/// Renames the temporary file `tmp` onto `path` when `written` is Ok, else removes it.
fn finish_partial(path: &Path, tmp: &Path, written: Result<()>) -> Result<()> {
    let done = written
        .map_err(|e| e.renaming(tmp, path))
        .and_then(|()| check_not_guarded(path))
        .and_then(|()| std::fs::rename(tmp, path).map_err(|e| PrtError::io(path, e)));
    if done.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    forget_partial(tmp);
    done
}

/// Writes `bytes` to `path` atomically ([`write_atomically`]).
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |mut file| {
        use std::io::Write;
        file.write_all(bytes)
            .and_then(|()| file.flush())
            .map_err(|e| PrtError::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_names_keep_the_extension() {
        let p = partial_path_of(
            Path::new("dir/out.prt"),
            "node-1-0a0b0c0d",
            42,
            "ff00",
            None,
        );
        assert_eq!(
            p,
            Path::new("dir/out.prt.partial-node-1-0a0b0c0d-42-ff00.prt")
        );
        let p = partial_path_of(Path::new("dir/out.prt"), "h-1", 42, "ab", Some("spill-sh"));
        assert_eq!(p, Path::new("dir/out.prt.partial-h-1-42-ab.spill-sh.prt"));
        assert_eq!(p.extension().and_then(|e| e.to_str()), Some("prt"));
        let p = partial_path_of(Path::new("noext"), "h-1", 7, "ab", None);
        assert_eq!(p, Path::new("noext.partial-h-1-7-ab"));
        // Nobody can guess the next name.
        assert_ne!(random_tag(), random_tag());
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("prt-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn partials_of_a_killed_run_are_removed_and_those_of_a_running_one_kept() {
        let dir = scratch("stale");
        let out = dir.join("out.prt");
        let owner = owner_tag();
        // No process has an id this large; process 1 always runs.
        let at = |pid: u32, part: Option<&str>| partial_path_of(&out, &owner, pid, "0123", part);
        let dead = at(4_000_000_000, None);
        let dead_spill = at(4_000_000_000, Some("spill-sh"));
        let alive = at(1, None);
        // Another container's file with the same host name: its owner tag differs.
        let elsewhere = partial_path_of(&out, "other-0000", 4_000_000_000, "0123", None);
        let other = dir.join("out.prt.notes.txt");
        for p in [&dead, &dead_spill, &alive, &elsewhere, &other] {
            std::fs::write(p, b"x").unwrap();
        }
        remove_stale_partials(&out);
        assert!(!dead.exists() && !dead_spill.exists());
        assert!(alive.exists() && elsewhere.exists() && other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn planted_links_are_never_followed() {
        let dir = scratch("planted");
        let out = dir.join("out.prt");
        let victim = dir.join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        let owner = owner_tag();
        let pid = std::process::id();
        // Links at the first names the writer will try, and at the name the cleanup sees as a
        // dead writer's.
        let planted: Vec<String> = (0..3).map(|i| format!("{i:016x}")).collect();
        for r in &planted {
            let link = partial_path_of(&out, &owner, pid, r, None);
            std::os::unix::fs::symlink(&victim, link).unwrap();
        }
        let stale = partial_path_of(&out, &owner, 4_000_000_000, "ab", None);
        std::os::unix::fs::symlink(&victim, &stale).unwrap();
        remove_stale_partials(&out);
        assert!(!stale.exists() && std::fs::symlink_metadata(&stale).is_err());
        // The writer skips the three links and takes the fourth name.
        let mut names = planted.clone().into_iter().chain(["free".to_string()]);
        let (tmp, file) =
            create_partial_as(&out, &owner, pid, None, &mut || names.next().unwrap()).unwrap();
        assert_eq!(tmp, partial_path_of(&out, &owner, pid, "free", None));
        drop(file);
        finish_partial(&out, &tmp, Ok(())).unwrap();
        // Every name planted: an error naming the output, and nothing written anywhere.
        let mut again = planted.iter().cycle().cloned();
        let e = create_partial_as(&out, &owner, pid, None, &mut || again.next().unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&out.display().to_string()) && e.contains("planted"),
            "{e}"
        );
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn two_writers_with_one_host_and_pid_leave_one_complete_file() {
        // Two containers with one host name whose writers got the same PID: their temporary
        // names still differ, so the output is always one writer's whole file.
        let dir = scratch("collide");
        let out = dir.join("out.bin");
        let (owner, pid) = ("shared-host-00000000".to_string(), 4242);
        let contents: Vec<Vec<u8>> = (0..2u8)
            .map(|k| {
                (0..(1 << 20))
                    .map(|i| (i as u8).wrapping_mul(k + 1) ^ k)
                    .collect()
            })
            .collect();
        for round in 0..20 {
            std::thread::scope(|s| {
                for bytes in &contents {
                    let (out, owner) = (&out, &owner);
                    s.spawn(move || {
                        let (tmp, mut file) =
                            create_partial_as(out, owner, pid, None, &mut random_tag).unwrap();
                        use std::io::Write;
                        let written = file.write_all(bytes).map_err(|e| PrtError::io(out, e));
                        drop(file);
                        finish_partial(out, &tmp, written).unwrap();
                    });
                }
            });
            let got = std::fs::read(&out).unwrap();
            assert!(contents.contains(&got), "round {round}: a mixed file");
        }
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "temporary files left"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_spill_leaves_no_file_in_its_folder() {
        let dir = scratch("spill-file");
        let out = dir.join("out.prt");
        let (path, mut file) = create_spill(&out, "sh").unwrap();
        use std::io::{Read, Seek, Write};
        file.write_all(b"spilled").unwrap();
        file.seek(std::io::SeekFrom::Start(0)).unwrap();
        let mut back = String::new();
        file.read_to_string(&mut back).unwrap();
        assert_eq!(back, "spilled");
        if cfg!(unix) {
            assert!(path.is_none());
            assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
