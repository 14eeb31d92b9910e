//! Errors of the engine: one enum of *kinds*, each carrying the place where it
//! happened (file and line, table and axis, channel and rows, ...) and what the
//! user needs to act on it. Context is added as an error rises
//! (`"fitting Cl, flap 15, alpha 12-14 deg"`) without losing its kind, so the
//! Python bindings can map each kind to one exception class.

use std::fmt;
use std::path::PathBuf;

/// The kind of an [`AeroError`], stable across context wrapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The caller passed something malformed (shape, ordering, NaN, name).
    InvalidInput,
    /// A value lies outside the range where it is defined.
    OutOfRange,
    /// Not enough data to do what was asked (points per parameter, rank).
    TooLittleData,
    /// An iterative method did not converge.
    NoConvergence,
    /// Reading or writing a file failed.
    Io,
    /// A file could not be parsed (syntax, schema, references).
    Parse,
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            ErrorKind::InvalidInput => "invalid input",
            ErrorKind::OutOfRange => "out of range",
            ErrorKind::TooLittleData => "too little data",
            ErrorKind::NoConvergence => "no convergence",
            ErrorKind::Io => "I/O error",
            ErrorKind::Parse => "parse error",
        };
        f.write_str(s)
    }
}

/// Every error `aero_core` returns.
///
/// Messages say what is wrong, where, and how to fix it. Use
/// [`AeroError::kind`] to dispatch on the kind whatever context was added.
#[derive(Debug, thiserror::Error)]
pub enum AeroError {
    /// Malformed input. `place` names the argument, table, axis, channel or row.
    #[error("{place}: {message}")]
    InvalidInput { place: String, message: String },

    /// A value outside its domain.
    #[error("{place}: {message}")]
    OutOfRange { place: String, message: String },

    /// Too few points, or a rank-deficient problem that cannot be solved as posed.
    #[error("{place}: {message}")]
    TooLittleData { place: String, message: String },

    /// An iterative method stopped without meeting its tolerance.
    #[error("{place}: did not converge after {iterations} iterations (residual {residual:.3e}): {message}")]
    NoConvergence {
        place: String,
        iterations: usize,
        residual: f64,
        message: String,
    },

    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// A file could not be parsed; `line` is 1-based (0 when unknown).
    #[error("{file}:{line}: {message}")]
    Parse {
        file: String,
        line: usize,
        message: String,
    },

    /// An error with a sentence of context in front of it.
    #[error("{context}: {source}")]
    Context {
        context: String,
        #[source]
        source: Box<AeroError>,
    },
}

impl AeroError {
    /// Malformed input at `place`.
    pub fn invalid(place: impl Into<String>, message: impl Into<String>) -> Self {
        AeroError::InvalidInput {
            place: place.into(),
            message: message.into(),
        }
    }

    /// A value out of its range at `place`.
    pub fn out_of_range(place: impl Into<String>, message: impl Into<String>) -> Self {
        AeroError::OutOfRange {
            place: place.into(),
            message: message.into(),
        }
    }

    /// Too little data at `place`.
    pub fn too_little(place: impl Into<String>, message: impl Into<String>) -> Self {
        AeroError::TooLittleData {
            place: place.into(),
            message: message.into(),
        }
    }

    /// A parse error in `file` at 1-based `line`.
    pub fn parse(file: impl Into<String>, line: usize, message: impl Into<String>) -> Self {
        AeroError::Parse {
            file: file.into(),
            line,
            message: message.into(),
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        AeroError::Io {
            path: path.into(),
            source,
        }
    }

    /// The kind of the innermost error, whatever context surrounds it.
    pub fn kind(&self) -> ErrorKind {
        match self {
            AeroError::InvalidInput { .. } => ErrorKind::InvalidInput,
            AeroError::OutOfRange { .. } => ErrorKind::OutOfRange,
            AeroError::TooLittleData { .. } => ErrorKind::TooLittleData,
            AeroError::NoConvergence { .. } => ErrorKind::NoConvergence,
            AeroError::Io { .. } => ErrorKind::Io,
            AeroError::Parse { .. } => ErrorKind::Parse,
            AeroError::Context { source, .. } => source.kind(),
        }
    }

    /// Wrap this error in a sentence of context.
    pub fn context(self, context: impl Into<String>) -> Self {
        AeroError::Context {
            context: context.into(),
            source: Box::new(self),
        }
    }
}

/// `Result` with [`AeroError`].
pub type Result<T, E = AeroError> = std::result::Result<T, E>;

/// Add context to the error of a `Result` as it rises.
pub trait ResultExt<T> {
    /// Prefix the error, if any, with `context`.
    fn context(self, context: impl Into<String>) -> Result<T>;
    /// Like [`ResultExt::context`], building the sentence only on error.
    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T>;
}

impl<T> ResultExt<T> for Result<T> {
    fn context(self, context: impl Into<String>) -> Result<T> {
        self.map_err(|e| e.context(context))
    }
    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| e.context(f()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kind_survives_context_and_message_reads_outside_in() {
        let e = AeroError::too_little("alpha bin 12.0-12.2 deg", "31 points for 4 parameters")
            .context("flap 15")
            .context("fitting Cl");
        assert_eq!(e.kind(), ErrorKind::TooLittleData);
        assert_eq!(
            e.to_string(),
            "fitting Cl: flap 15: alpha bin 12.0-12.2 deg: 31 points for 4 parameters"
        );
    }

    #[test]
    fn parse_error_names_file_and_line() {
        let e = AeroError::parse("model.dml", 42, "unknown varID 'XYZ'");
        assert_eq!(e.to_string(), "model.dml:42: unknown varID 'XYZ'");
        assert_eq!(e.kind(), ErrorKind::Parse);
    }
}
