//! A panic inside a third-party format reader (the `parquet` crate asserts on some
//! corrupt files instead of returning an error) becomes an error naming the file. While
//! such a call runs, [`is_active`] is true, so that a program's panic hook can stay quiet
//! about a panic that is reported as an error anyway.

use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};

thread_local! {
    static ACTIVE: Cell<bool> = const { Cell::new(false) };
}

/// Whether this thread is inside [`guarded`].
pub fn is_active() -> bool {
    ACTIVE.with(Cell::get)
}

/// Runs `f`; a panic in it is returned as its message.
pub fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    let outer = ACTIVE.with(|a| a.replace(true));
    let r = catch_unwind(AssertUnwindSafe(f));
    ACTIVE.with(|a| a.set(outer));
    r.map_err(|p| {
        let msg = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown failure".into());
        format!("corrupt file (the reader failed: {})", msg.replace('\n', " "))
    })
}
