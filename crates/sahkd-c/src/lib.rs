//! The C API of sahkd. Every `extern "C"` function here is one line that hands its arguments
//! to [`guard`], which catches panics, turns errors into a [`sahkd_status`] and keeps the
//! message for [`sahkd_last_error`]; the work happens in the modules below, in safe Rust
//! after [`checked`] has turned each raw pointer into a reference or a slice.
//!
//! Names follow C conventions (`sahkd_tree`, `SAHKD_OK`) because cbindgen copies them into
//! include/sahkd.h as they are.
#![allow(non_camel_case_types)]
// Every pointer is checked (checked.rs) before it is read; the safety contract of each
// function is the header's documentation, written for C callers.
#![allow(clippy::missing_safety_doc)]

mod checked;
mod mesh;
mod options;
mod queries;
mod scene;

pub use mesh::*;
pub use options::*;
pub use queries::*;
pub use scene::*;

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// What a call did. Anything but `SAHKD_OK` leaves the outputs as documented for the call
/// (output handles set to NULL) and a message for sahkd_last_error().
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum sahkd_status {
    SAHKD_OK = 0,
    /// A required pointer (handle, array, output) was NULL.
    SAHKD_ERROR_NULL = 1,
    /// A pointer or stride is not a multiple of its element's alignment.
    SAHKD_ERROR_ALIGNMENT = 2,
    /// An argument is out of range: an option, a count whose arrays overflow the address
    /// space, an unknown name or flag, a singular transform, a geometry id that does not exist.
    SAHKD_ERROR_INVALID_ARGUMENT = 3,
    /// The mesh is not valid: non-finite vertices, indices out of range, a file that does not
    /// parse.
    SAHKD_ERROR_INVALID_MESH = 4,
    /// A file could not be read or written.
    SAHKD_ERROR_IO = 5,
    /// The bytes or file are not a valid sahkd tree.
    SAHKD_ERROR_INVALID_TREE = 6,
    /// The output array is too small; the call says how much it needs.
    SAHKD_ERROR_BUFFER_TOO_SMALL = 7,
    /// A bug inside sahkd (a Rust panic, caught at the boundary).
    SAHKD_ERROR_INTERNAL = 8,
}

/// A failed call: its status and a message naming what was wrong.
#[derive(Debug)]
pub(crate) struct Error {
    pub status: sahkd_status,
    pub message: String,
}

pub(crate) type Result<T> = std::result::Result<T, Error>;

pub(crate) fn error<T>(status: sahkd_status, message: impl Into<String>) -> Result<T> {
    Err(Error {
        status,
        message: message.into(),
    })
}

pub(crate) fn invalid<T>(message: impl Into<String>) -> Result<T> {
    error(sahkd_status::SAHKD_ERROR_INVALID_ARGUMENT, message)
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    // A NUL inside a message would cut it short in C; none of ours has one, but say so if so.
    let text = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// Runs one call: its error becomes a status and the thread's last error, and a panic
/// becomes `SAHKD_ERROR_INTERNAL` instead of unwinding into C.
pub(crate) fn guard(f: impl FnOnce() -> Result<()>) -> sahkd_status {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => sahkd_status::SAHKD_OK,
        Ok(Err(e)) => {
            set_last_error(&e.message);
            e.status
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            set_last_error(&format!("internal error in sahkd (please report): {what}"));
            sahkd_status::SAHKD_ERROR_INTERNAL
        }
    }
}

/// The message of the last call on this thread that failed ("" if none has). The text stays
/// valid until the next failing call on the same thread; copy it to keep it.
#[no_mangle]
pub extern "C" fn sahkd_last_error() -> *const c_char {
    // Reading a thread-local cannot panic except during thread teardown; then say nothing.
    catch_unwind(|| LAST_ERROR.with(|e| e.borrow().as_ptr())).unwrap_or(c"".as_ptr())
}

/// The name of a status, such as "SAHKD_ERROR_NULL" (a static string; "unknown status" for a
/// number that is none).
#[no_mangle]
pub extern "C" fn sahkd_status_name(status: i32) -> *const c_char {
    use sahkd_status::*;
    let all = [
        (SAHKD_OK, c"SAHKD_OK"),
        (SAHKD_ERROR_NULL, c"SAHKD_ERROR_NULL"),
        (SAHKD_ERROR_ALIGNMENT, c"SAHKD_ERROR_ALIGNMENT"),
        (
            SAHKD_ERROR_INVALID_ARGUMENT,
            c"SAHKD_ERROR_INVALID_ARGUMENT",
        ),
        (SAHKD_ERROR_INVALID_MESH, c"SAHKD_ERROR_INVALID_MESH"),
        (SAHKD_ERROR_IO, c"SAHKD_ERROR_IO"),
        (SAHKD_ERROR_INVALID_TREE, c"SAHKD_ERROR_INVALID_TREE"),
        (
            SAHKD_ERROR_BUFFER_TOO_SMALL,
            c"SAHKD_ERROR_BUFFER_TOO_SMALL",
        ),
        (SAHKD_ERROR_INTERNAL, c"SAHKD_ERROR_INTERNAL"),
    ];
    let name: &'static CStr = all
        .iter()
        .find(|(s, _)| *s as i32 == status)
        .map_or(c"unknown status", |(_, n)| n);
    name.as_ptr()
}

/// The library's version, such as "0.1.0" (a static string).
#[no_mangle]
pub extern "C" fn sahkd_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}
