//! The library's one error type. Every error names what it is about: the file (and the line
//! or item where there is one), the option, or the numerical condition, in plain words.
//! The binary adds context with `anyhow` and maps [`Error::exit_code`] to the process status.

use std::path::PathBuf;

/// Everything that can go wrong in the library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A syntax or value error at a known line of an input file (1-based line number).
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// An input file is well formed but its content is unusable (item named in `message`).
    #[error("{path}: {message}")]
    Input { path: PathBuf, message: String },
    /// A command-line option or configuration value is out of range.
    #[error("invalid value for {option}: {message}")]
    Usage { option: String, message: String },
    /// The system cannot be solved as posed (e.g. ρ = 1 in a closed scene).
    #[error("{0}")]
    Numerical(String),
    /// An internal invariant failed: a bug, not bad input.
    #[error("internal error: {0}")]
    Internal(String),
}

impl Error {
    /// Process exit status for this error: 2 for bad input or usage, 1 for internal failures.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Parse { .. } | Error::Input { .. } | Error::Usage { .. } => 2,
            Error::Io { source, .. } => match source.kind() {
                std::io::ErrorKind::NotFound
                | std::io::ErrorKind::PermissionDenied
                | std::io::ErrorKind::IsADirectory
                | std::io::ErrorKind::InvalidInput
                | std::io::ErrorKind::InvalidData => 2,
                _ => 1,
            },
            Error::Numerical(_) => 2,
            Error::Internal(_) => 1,
        }
    }

    /// Shorthand for an [`Error::Io`] on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Shorthand for an [`Error::Usage`].
    pub fn usage(option: &str, message: impl Into<String>) -> Self {
        Error::Usage {
            option: option.to_string(),
            message: message.into(),
        }
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;
