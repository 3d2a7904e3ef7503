//! The one error type of the library. Every message names what it is about: the file and the
//! field, or the argument and the value. Library code returns these; only the CLI prints them.

use std::path::{Path, PathBuf};

/// Everything that can go wrong on user input or I/O.
#[derive(Debug, thiserror::Error)]
pub enum PrtError {
    /// The operating system refused to read or write a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file that could not be read or written.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its content is not what it should be.
    #[error("{}: {message}", path.display())]
    File {
        /// The file whose content is wrong.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A scene file names something wrong: the file, the line (when known) and the field.
    #[error("{}{}: field `{field}`: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// 1-based line of the field (or of its nearest enclosing field) in the file; `None` when
        /// no line is known.
        line: Option<usize>,
        /// Dotted path of the field, such as `camera.eye` or `shape[2].radius`.
        field: String,
        /// What is wrong with the field.
        message: String,
    },
    /// An argument or a combination of inputs that cannot work.
    #[error("invalid {what}: {message}")]
    Invalid {
        /// The argument or input that is wrong, such as `environment` or `reference`.
        what: String,
        /// Why it cannot work.
        message: String,
    },
    /// The GPU back-end is unavailable or failed.
    #[error("GPU: {0}")]
    Gpu(String),
    /// The work was stopped by its cancel token (`bake::Cancel`) before it finished.
    #[error("cancelled")]
    Cancelled,
}

/// Result with [`PrtError`].
pub type Result<T> = std::result::Result<T, PrtError>;

impl PrtError {
    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        PrtError::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
    /// A content error in the file `path`.
    pub fn file(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        PrtError::File {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }
    /// The same error naming `to` wherever it named `from` (a temporary file stands for the
    /// file the user asked for).
    pub fn renaming(self, from: &Path, to: &Path) -> Self {
        match self {
            PrtError::Io { path, source } if path == from => PrtError::Io {
                path: to.to_path_buf(),
                source,
            },
            PrtError::File { path, message } if path == from => PrtError::File {
                path: to.to_path_buf(),
                message,
            },
            e => e,
        }
    }
    /// An invalid argument or input named `what`.
    pub fn invalid(what: impl Into<String>, message: impl Into<String>) -> Self {
        PrtError::Invalid {
            what: what.into(),
            message: message.into(),
        }
    }
}
