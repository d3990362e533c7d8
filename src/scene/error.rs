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
    #[error("{}: bad texture: {source}{}", path.display(), in_context(context))]
    Texture {
        /// The texture file (the scene file itself for embedded images).
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: ImageError,
        /// Which material or image of which file refers to it, when not obvious.
        context: Option<String>,
    },
    /// A binary glTF container whose chunks cannot be found.
    #[error("{file}: malformed .glb: {source}")]
    Glb {
        /// The `.glb` file.
        file: String,
        /// What is wrong with its layout.
        #[source]
        source: GlbError,
    },
    /// A URI of a glTF file that cannot be resolved to bytes.
    #[error("{file}: {what}: {source}")]
    Uri {
        /// The glTF file.
        file: String,
        /// Which buffer or image the URI belongs to.
        what: String,
        /// What is wrong with the URI.
        #[source]
        source: UriError,
    },
    /// A glTF animation sampler whose keys cannot be interpolated.
    #[error("{file}: {context}: {source}")]
    Sampler {
        /// The glTF file.
        file: String,
        /// Which animation channel uses the sampler.
        context: String,
        /// What is wrong with its keys.
        #[source]
        source: SamplerError,
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

/// ` (context)`, or nothing: where a texture error was met, appended to its message.
fn in_context(context: &Option<String>) -> String {
    context
        .as_ref()
        .map_or_else(String::new, |c| format!(" ({c})"))
}

/// Why image bytes could not be decoded into a texture.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The bytes start with no magic number this renderer knows.
    #[error("unsupported image format (PNG, JPEG or binary PPM expected)")]
    UnknownFormat,
    /// Not a binary (`P6`) PPM file.
    #[error("not a binary PPM (missing P6 magic)")]
    NotPpm,
    /// A PPM header field (`width`, `height` or `maxval`) is absent or not a number.
    #[error("header {0} is missing or not a number")]
    PpmHeaderField(&'static str),
    /// The PPM header runs straight into the pixel data.
    #[error("header not followed by whitespace")]
    PpmHeaderEnd,
    /// A PPM `maxval` that no sample size can hold.
    #[error("maxval {0} out of range 1..=65535")]
    PpmMaxval(u32),
    /// Fewer PPM pixel bytes than the header promises.
    #[error("truncated pixel data: {got} bytes, {need} expected for {width}x{height}")]
    PpmTruncated {
        /// Bytes present after the header.
        got: usize,
        /// Bytes the header's size and maxval need.
        need: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },
    /// An empty image, or one larger than
    /// [`MAX_TEXTURE_SIDE`](super::texture::MAX_TEXTURE_SIDE) on a side.
    #[error("absurd size {width}x{height}")]
    Size {
        /// Width in texels.
        width: u32,
        /// Height in texels.
        height: u32,
    },
    /// The PNG or JPEG decoder failed.
    #[error("cannot decode {mime}: {source}")]
    Decode {
        /// The format the bytes were sniffed as.
        mime: &'static str,
        /// The decoder's error (boxed: it is several times larger than the others, and
        /// every scene `Result` would carry its size).
        #[source]
        source: Box<::gltf::Error>,
    },
    /// The decoder's pixel buffer does not match the size and format it reported.
    #[error("decoder returned {got} bytes for {width}x{height} {format}")]
    DecodedSize {
        /// Bytes returned.
        got: usize,
        /// Reported width.
        width: u32,
        /// Reported height.
        height: u32,
        /// Reported pixel format.
        format: String,
    },
    /// The in-memory document used to reach the decoder could not be built (a bug).
    #[error("internal: cannot build the image decoding document: {0}")]
    DecodingDocument(#[source] serde_json::Error),
    /// The in-memory document lost its image (a bug).
    #[error("internal: no image in the decoding document")]
    NoDecodingImage,
}

/// Why a binary glTF (`.glb`) file could not be split into its JSON and BIN chunks.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GlbError {
    /// Shorter than the 12-byte header.
    #[error("truncated: {0} bytes, the header alone needs 12")]
    ShortHeader(usize),
    /// A container version other than 2.
    #[error("container version {0} (2 expected)")]
    Version(u32),
    /// The header's length exceeds the file.
    #[error("truncated: the header declares {declared} bytes, the file has {actual}")]
    ShortFile {
        /// Length in the header.
        declared: usize,
        /// Length of the file.
        actual: usize,
    },
    /// The header's length is too small to hold the header itself.
    #[error("the header declares a length of {0} bytes")]
    TinyLength(usize),
    /// A chunk header cut off by the end of the data.
    #[error("truncated chunk header at byte {0}")]
    ChunkHeader(usize),
    /// A chunk longer than the data left.
    #[error("truncated: chunk at byte {at} declares {len} bytes, {remain} remain")]
    ShortChunk {
        /// Offset of the chunk header.
        at: usize,
        /// Declared chunk length.
        len: u32,
        /// Bytes left after the chunk header.
        remain: usize,
    },
    /// A JSON chunk after the first.
    #[error("unexpected second JSON chunk at byte {0}")]
    SecondJson(usize),
    /// The first chunk is of another type.
    #[error("the first chunk is not JSON")]
    FirstNotJson,
    /// No chunks at all.
    #[error("no JSON chunk")]
    NoJson,
}

/// Why a glTF buffer or image URI could not be turned into bytes or a path.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UriError {
    /// A `data:` URI without `;base64,`.
    #[error("data URI is not base64")]
    DataNotBase64,
    /// A character outside both base64 alphabets.
    #[error("bad data URI: invalid base64 character at offset {0}")]
    Base64Character(usize),
    /// Data after `=` padding.
    #[error("bad data URI: base64 data continues after padding at offset {0}")]
    Base64AfterPadding(usize),
    /// A `%` not followed by two hexadecimal digits.
    #[error("bad percent escape at offset {0}")]
    PercentEscape(usize),
    /// Percent escapes that form no valid UTF-8 path.
    #[error("percent escapes do not decode to UTF-8")]
    PercentNotUtf8,
    /// A scheme other than `data:` and `file:`.
    #[error("URI scheme of `{0}` is not supported (relative paths, file: and data: are)")]
    Scheme(String),
}

/// Why the keys of a glTF animation sampler cannot be interpolated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SamplerError {
    /// No keys at all.
    #[error("sampler has no keys")]
    NoKeys,
    /// A key time that is NaN or infinite.
    #[error("key time {0} is not finite")]
    NonFiniteTime(usize),
    /// Key times out of order.
    #[error("key times decrease at key {key}: {time} after {previous}")]
    DecreasingTime {
        /// Index of the offending key.
        key: usize,
        /// Its time.
        time: f32,
        /// The time of the key before it.
        previous: f32,
    },
    /// Output values that do not match the key count.
    #[error("{values} output values for {keys} keys ({expected} expected)")]
    ValueCount {
        /// Values given.
        values: usize,
        /// Keys given.
        keys: usize,
        /// Values the interpolation needs for that many keys.
        expected: usize,
    },
    /// An output value with a NaN or infinite component.
    #[error("output value {0} is not finite")]
    NonFiniteValue(usize),
}
