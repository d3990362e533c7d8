//! Library errors as Python exceptions, with the text the command line prints after
//! `error: `: bad settings are ValueError, unreadable or unwritable files OSError,
//! anything else RuntimeError.

use frameless::{
    evaluation::EvalError, methods::MethodError, scene::SceneError, settings::Setting,
};
use pyo3::{
    exceptions::{PyOSError, PyRuntimeError, PyValueError},
    PyErr,
};

/// An error and its causes joined by ": ", leaving out a cause whose text the message
/// already ends with, as the command line joins them.
pub fn message(e: &(dyn std::error::Error + 'static)) -> String {
    let mut msg = String::new();
    let mut cause = Some(e);
    while let Some(c) = cause {
        // A bad setting is named by its Python keyword, where the command line names
        // its option.
        let text = match c.downcast_ref::<EvalError>() {
            Some(EvalError::Config { setting, why }) => format!("{} {why}", keyword(*setting)),
            _ => c.to_string(),
        };
        if !msg.ends_with(&text) {
            if !msg.is_empty() {
                msg.push_str(": ");
            }
            msg.push_str(&text);
        }
        cause = c.source();
    }
    msg
}

/// The keyword of `frameless.evaluate`, `live` or `render` that sets `setting`.
fn keyword(setting: Setting) -> &'static str {
    match setting {
        // `live`'s recorded seconds are its `duration=`, as on the command line.
        Setting::Seconds => "duration",
        // The reason names the keyword (`ring factor 100 out of range …`).
        Setting::Adaptive => "adaptive:",
        s => s.key(),
    }
}

/// A bad argument, with the reason the command line gives for it.
pub fn value(why: impl Into<String>) -> PyErr {
    PyValueError::new_err(why.into())
}

/// A scene or camera path that cannot be read (OSError) or is malformed (ValueError).
pub fn scene(e: SceneError) -> PyErr {
    let text = message(&e);
    match e {
        SceneError::Io { .. } => PyOSError::new_err(text),
        _ => PyValueError::new_err(text),
    }
}

/// An evaluation's or sequence's error.
pub fn eval(e: EvalError) -> PyErr {
    let text = message(&e);
    match e {
        EvalError::Config { .. } | EvalError::UnknownAnimation { .. } => value(text),
        EvalError::Method(m) => method_kind(m, text),
        EvalError::Io { .. } => PyOSError::new_err(text),
        _ => PyRuntimeError::new_err(text),
    }
}

/// A method that cannot run as asked: its settings are wrong (ValueError) or a check
/// of its own data failed (RuntimeError).
pub fn method(e: MethodError) -> PyErr {
    let text = message(&e);
    method_kind(e, text)
}

fn method_kind(e: MethodError, text: String) -> PyErr {
    match e {
        MethodError::RateTooLow { .. } | MethodError::Parameter { .. } | MethodError::Budget(_) => {
            value(text)
        }
        _ => PyRuntimeError::new_err(text),
    }
}
