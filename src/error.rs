//! The library's one error type. Every error names what it is about, in the library's own
//! words: the file (and the line or item where there is one), the setting (by its name in
//! the library: `max_edge`, `form_factors.samples`, …), or the numerical condition. A program
//! built on the library maps setting names to its own option names (the `radiosity` binary
//! says `--max-edge`) and [`Error::exit_code`] to its process status.

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
    /// A setting is out of range or malformed. `name` is the setting's name in the library:
    /// a field of [`crate::pipeline::Settings`] (`max_edge`, `crease_degrees`,
    /// `form_factors.samples`, `solver.tolerance`, …), of [`crate::render::View`]
    /// (`view.spp`, …), or one of `exposure`, `output`, `camera`, `reflectance`, `emission`.
    #[error("invalid {name}: {message}")]
    Setting { name: String, message: String },
    /// The system cannot be solved as posed (e.g. ρ = 1 in a closed scene).
    #[error("{0}")]
    Numerical(String),
    /// An internal invariant failed: a bug, not bad input.
    #[error("internal error: {0}")]
    Internal(String),
}

impl Error {
    /// Process exit status for this error: 2 for bad input or settings, 1 for internal failures.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Parse { .. } | Error::Input { .. } | Error::Setting { .. } => 2,
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

    /// Shorthand for an [`Error::Setting`] about the setting `name`.
    pub fn setting(name: &str, message: impl Into<String>) -> Self {
        Error::Setting {
            name: name.to_string(),
            message: message.into(),
        }
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;
