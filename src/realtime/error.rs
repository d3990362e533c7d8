//! The real-time mode's errors, at the bottom of its files so that every one of them
//! can return them.

/// Errors of the real-time mode.
#[derive(Debug, thiserror::Error)]
pub enum RealtimeError {
    /// A setting is out of range.
    #[error("invalid real-time setting: {0}")]
    Config(String),
    /// A thread could not be started.
    #[error("starting the {what} thread: {source}")]
    Spawn {
        /// Which thread.
        what: &'static str,
        /// Why.
        source: std::io::Error,
    },
    /// A pipeline thread panicked (a bug).
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
    /// Output could not be written.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The window system failed.
    #[error("window: {0}")]
    Window(String),
    /// The method cannot reconstruct on the GPU it was given (`--recon gpu|auto`).
    #[error("{method}: {why}")]
    Gpu {
        /// The real-time method.
        method: &'static str,
        /// Why (the GPU reconstructor's error).
        why: String,
    },
}
