//! The `frameless` command from Python: the binary's own command-line module, compiled
//! into the extension, so that `pip install` gives the package's `frameless` console
//! script and `python -m frameless` the very command `cargo build` makes.

#[path = "../../src/cli/mod.rs"]
// The binary's module; what only its `main` or its tests use is unused here.
#[allow(dead_code)]
mod command;

use pyo3::prelude::*;

/// main(argv)
/// --
///
/// Run the `frameless` command with `argv` (the program's name first) and return its
/// exit status, with the GIL released. A usage error (and `--help`) ends the process
/// as the command does.
#[pyfunction]
fn main(py: Python<'_>, argv: Vec<String>) -> u8 {
    let status = py.detach(|| command::status(argv));
    // The command's output goes through Rust's buffered stdout, which nothing else
    // flushes before the interpreter exits.
    use std::io::Write;
    let _ = std::io::stdout().flush();
    status
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(main, m)?)
}
