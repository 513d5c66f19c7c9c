//! The exceptions: `bvhc.Error` and one subclass for each kind of failure the command line tells apart by its
//! exit code, carrying the command line's messages.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

use bvhc::convert::ConvertError;
use bvhc::import::ErrorKind;

create_exception!(bvhc, Error, PyException, "Every error bvhc raises.");
create_exception!(
    bvhc,
    InvalidInputError,
    Error,
    "A scene, array or ray that breaks a rule (the message names the file, the part and the rule)."
);
create_exception!(
    bvhc,
    InvalidFileError,
    Error,
    "A .bvh file that breaks a rule of the format (the message names it)."
);
create_exception!(
    bvhc,
    OptionsError,
    InvalidInputError,
    "Options that cannot be honoured (the command line's usage errors)."
);
create_exception!(bvhc, OutOfMemoryError, Error, "Memory the conversion or file needs was refused.");
create_exception!(bvhc, IoError, Error, "A file that cannot be read or written.");
create_exception!(bvhc, InternalError, Error, "A bug in bvhc, caught: please report it with the input.");

/// Adds the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("InvalidInputError", py.get_type::<InvalidInputError>())?;
    m.add("InvalidFileError", py.get_type::<InvalidFileError>())?;
    m.add("OptionsError", py.get_type::<OptionsError>())?;
    m.add("OutOfMemoryError", py.get_type::<OutOfMemoryError>())?;
    m.add("IoError", py.get_type::<IoError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    Ok(())
}

/// The exception for a failed conversion, as `bvhc`'s exit codes sort them.
pub fn conversion(error: ConvertError) -> PyErr {
    let message = error.to_string();
    match error {
        ConvertError::Options(_) => OptionsError::new_err(message),
        ConvertError::Import(e) if e.kind == ErrorKind::Unreadable => IoError::new_err(message),
        ConvertError::Import(_) | ConvertError::TooLarge { .. } => InvalidInputError::new_err(message),
        ConvertError::OutputIsInput { .. } => IoError::new_err(message),
        ConvertError::Write(e) => loader(&e, message),
        ConvertError::OutOfMemory { .. } => OutOfMemoryError::new_err(message),
        _ => InternalError::new_err(message),
    }
}

/// The exception for a loader error, with `message` (which names the file).
pub fn loader(error: &bvhc::loader::Error, message: String) -> PyErr {
    match error {
        bvhc::loader::Error::Io { .. } | bvhc::loader::Error::Unwritable(_) => IoError::new_err(message),
        bvhc::loader::Error::OutOfMemory { .. } => OutOfMemoryError::new_err(message),
        // Positions or transforms that do not fit the file, or a file a refit cannot take.
        bvhc::loader::Error::Refit(_) => InvalidInputError::new_err(message),
        _ => InvalidFileError::new_err(message),
    }
}

/// The exception for an asset whose positions cannot be given to a file, with `message`: an unreadable asset is
/// an `IoError`, the rest (a broken asset, another topology, a file without ids) `InvalidInputError`.
pub fn posed(error: &bvhc::posed::PosedError, message: String) -> PyErr {
    match error {
        bvhc::posed::PosedError::Import(e) if e.kind == ErrorKind::Unreadable => IoError::new_err(message),
        _ => InvalidInputError::new_err(message),
    }
}
