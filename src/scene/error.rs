//! Errors of scene loading, with enough context to find the problem.

use std::path::PathBuf;

/// What went wrong while reading a scene, texture or camera path.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read.
    #[error("{}: cannot read: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's explanation.
        message: String,
    },
    /// Malformed text at a known place.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file (as the user or the including file named it).
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What was expected or wrong.
        message: String,
    },
    /// A texture file is malformed.
    #[error("{}: bad texture: {message}", path.display())]
    Texture {
        /// The texture file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A scene path whose kind is not recognised.
    #[error("{}: unknown scene format (expected .aff, .gltf, .glb or .obj, or a built-in name: {builtins})", path.display())]
    UnknownFormat {
        /// The path given.
        path: PathBuf,
        /// Names of the built-in scenes.
        builtins: String,
    },
    /// The scene loaded but cannot be rendered as it is.
    #[error("{name}: {message}")]
    Invalid {
        /// Scene name or file.
        name: String,
        /// What is wrong.
        message: String,
    },
}
