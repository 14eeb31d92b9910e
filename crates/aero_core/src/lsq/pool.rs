//! Work buffers recycled between least-squares calls.
//!
//! Long FFTs and the column-major copy of a large regressor matrix need
//! buffers of millions of values; on first touch every fresh page costs a
//! page fault, which for N = 10⁶ costs as much as the arithmetic, so such
//! buffers are recycled (up to [`POOL_MAX_BYTES`] kept). A taken buffer
//! holds stale values: every caller overwrites all of it, so results never
//! depend on old contents.

use std::sync::Mutex;

use realfft::num_complex::Complex;

/// Largest total size (bytes) of work buffers kept between calls.
const POOL_MAX_BYTES: usize = 1 << 30;

/// The recycled buffers (see the module docs).
struct Pool {
    real: Vec<Vec<f64>>,
    cplx: Vec<Vec<Complex<f64>>>,
}

static POOL: Mutex<Pool> = Mutex::new(Pool {
    real: Vec::new(),
    cplx: Vec::new(),
});

fn pool() -> std::sync::MutexGuard<'static, Pool> {
    POOL.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn pool_bytes(p: &Pool) -> usize {
    p.real.iter().map(|v| v.capacity() * 8).sum::<usize>()
        + p.cplx.iter().map(|v| v.capacity() * 16).sum::<usize>()
}

/// A real buffer of `len` values (contents unspecified), recycled if possible.
pub(crate) fn take_real(len: usize) -> Vec<f64> {
    let mut v = {
        let mut pl = pool();
        match pl.real.iter().position(|b| b.capacity() >= len) {
            Some(i) => pl.real.swap_remove(i),
            None => Vec::new(),
        }
    };
    if v.len() >= len {
        v.truncate(len);
    } else {
        v.resize(len, 0.0);
    }
    v
}

/// A complex buffer of `len` values (contents unspecified), recycled if possible.
pub(crate) fn take_cplx(len: usize) -> Vec<Complex<f64>> {
    let mut v = {
        let mut pl = pool();
        match pl.cplx.iter().position(|b| b.capacity() >= len) {
            Some(i) => pl.cplx.swap_remove(i),
            None => Vec::new(),
        }
    };
    if v.len() >= len {
        v.truncate(len);
    } else {
        v.resize(len, Complex::new(0.0, 0.0));
    }
    v
}

pub(crate) fn give_real(v: Vec<f64>) {
    if v.capacity() == 0 {
        return;
    }
    let mut pl = pool();
    if pool_bytes(&pl) + v.capacity() * 8 <= POOL_MAX_BYTES {
        pl.real.push(v);
    }
}

pub(crate) fn give_cplx(v: Vec<Complex<f64>>) {
    if v.capacity() == 0 {
        return;
    }
    let mut pl = pool();
    if pool_bytes(&pl) + v.capacity() * 16 <= POOL_MAX_BYTES {
        pl.cplx.push(v);
    }
}
