//! Raw pointers from C turned into references and slices, or into an error naming the
//! argument: NULL, misaligned, or a count whose array would not fit the address space.
//! Nothing is read before its pointer passed these checks.

use crate::{error, invalid, sahkd_status, Result};
use std::ffi::{c_char, CStr, OsStr};
use std::mem::{align_of, size_of};
use std::path::PathBuf;

fn null<T>(what: &str) -> Result<T> {
    error(sahkd_status::SAHKD_ERROR_NULL, format!("{what} is NULL"))
}

fn aligned<T>(p: *const T, what: &str) -> Result<()> {
    if (p as usize) % align_of::<T>() != 0 {
        return error(
            sahkd_status::SAHKD_ERROR_ALIGNMENT,
            format!("{what} ({p:p}) is not aligned to {} bytes", align_of::<T>()),
        );
    }
    Ok(())
}

/// `*p`, for a handle or a struct passed by pointer.
pub unsafe fn get<'a, T>(p: *const T, what: &str) -> Result<&'a T> {
    if p.is_null() {
        return null(what);
    }
    aligned(p, what)?;
    Ok(&*p)
}

/// `*p`, mutable.
pub unsafe fn get_mut<'a, T>(p: *mut T, what: &str) -> Result<&'a mut T> {
    get(p, what)?;
    Ok(&mut *p)
}

/// Writes `value` to an output pointer.
pub unsafe fn put<T>(p: *mut T, value: T, what: &str) -> Result<()> {
    *get_mut(p, what)? = value;
    Ok(())
}

/// Bytes spanned by `count` elements of `size` bytes, `stride` apart, or an error.
fn span(count: usize, size: usize, stride: usize, what: &str) -> Result<usize> {
    let bytes = (count - 1)
        .checked_mul(stride)
        .and_then(|b| b.checked_add(size))
        .filter(|&b| b <= isize::MAX as usize);
    bytes.map_or_else(
        || {
            invalid(format!(
                "{what}: {count} elements of {stride} bytes overflow the address space"
            ))
        },
        Ok,
    )
}

/// `count` contiguous elements at `p` (NULL is allowed when `count` is 0).
pub unsafe fn slice<'a, T>(p: *const T, count: usize, what: &str) -> Result<&'a [T]> {
    if count == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return null(what);
    }
    aligned(p, what)?;
    let bytes = span(count, size_of::<T>(), size_of::<T>(), what)?;
    if (p as usize).checked_add(bytes).is_none() {
        return invalid(format!(
            "{what}: {count} elements run past the end of memory"
        ));
    }
    Ok(std::slice::from_raw_parts(p, count))
}

/// `count` elements `stride` bytes apart (0: packed), read or written one at a time.
#[derive(Clone, Copy)]
pub struct Strided<T> {
    base: *mut T,
    stride: usize,
    count: usize,
}

// The caller of the C function promises the memory stays valid and unshared for the call;
// workers of one call touch disjoint elements.
unsafe impl<T> Send for Strided<T> {}
unsafe impl<T> Sync for Strided<T> {}

impl<T: Copy> Strided<T> {
    pub unsafe fn new(p: *const T, count: usize, stride: usize, what: &str) -> Result<Self> {
        let stride = if stride == 0 { size_of::<T>() } else { stride };
        let s = Strided {
            base: p as *mut T,
            stride,
            count,
        };
        if count == 0 {
            return Ok(s);
        }
        if p.is_null() {
            return null(what);
        }
        aligned(p, what)?;
        if stride % align_of::<T>() != 0 {
            return error(
                sahkd_status::SAHKD_ERROR_ALIGNMENT,
                format!(
                    "{what}: stride {stride} is not a multiple of {} bytes",
                    align_of::<T>()
                ),
            );
        }
        if stride < size_of::<T>() {
            return invalid(format!(
                "{what}: stride {stride} is less than the element's {} bytes",
                size_of::<T>()
            ));
        }
        let bytes = span(count, size_of::<T>(), stride, what)?;
        if (p as usize).checked_add(bytes).is_none() {
            return invalid(format!(
                "{what}: {count} elements run past the end of memory"
            ));
        }
        Ok(s)
    }

    /// An optional array: NULL gives `None`.
    pub unsafe fn optional(
        p: *const T,
        count: usize,
        stride: usize,
        what: &str,
    ) -> Result<Option<Self>> {
        if p.is_null() {
            Ok(None)
        } else {
            Self::new(p, count, stride, what).map(Some)
        }
    }

    fn at(&self, i: usize) -> *mut T {
        assert!(i < self.count, "element {i} of {}", self.count);
        (self.base as *mut u8).wrapping_add(i * self.stride) as *mut T
    }

    pub fn read(&self, i: usize) -> T {
        unsafe { self.at(i).read() }
    }

    pub fn write(&self, i: usize, value: T) {
        unsafe { self.at(i).write(value) }
    }
}

/// A path given as a NUL-terminated string (any bytes but NUL, as the system takes them).
pub unsafe fn path(p: *const c_char, what: &str) -> Result<PathBuf> {
    if p.is_null() {
        return null(what);
    }
    let bytes = CStr::from_ptr(p).to_bytes();
    #[cfg(unix)]
    let path = PathBuf::from(<OsStr as std::os::unix::ffi::OsStrExt>::from_bytes(bytes));
    #[cfg(not(unix))]
    let path = PathBuf::from(
        std::str::from_utf8(bytes)
            .map_err(|_| crate::Error {
                status: sahkd_status::SAHKD_ERROR_INVALID_ARGUMENT,
                message: format!("{what} is not UTF-8"),
            })?
            .to_owned(),
    );
    Ok(path)
}

/// A NUL-terminated UTF-8 string.
pub unsafe fn text<'a>(p: *const c_char, what: &str) -> Result<&'a str> {
    if p.is_null() {
        return null(what);
    }
    CStr::from_ptr(p)
        .to_str()
        .or_else(|_| invalid(format!("{what} is not UTF-8")))
}

/// Sets an output handle to NULL first, so that it is NULL on every failure.
pub unsafe fn clear_out<T>(out: *mut *mut T, what: &str) -> Result<()> {
    put(out, std::ptr::null_mut(), what)
}

/// Hands a new handle to C.
pub unsafe fn give<T>(out: *mut *mut T, value: T) {
    *out = Box::into_raw(Box::new(value));
}

/// Takes a handle back from C and drops it (NULL: nothing).
pub unsafe fn free<T>(p: *mut T) {
    if !p.is_null() && (p as usize) % align_of::<T>() == 0 {
        drop(Box::from_raw(p));
    }
}
