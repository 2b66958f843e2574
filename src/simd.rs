//! Run-time CPU dispatch for the hot loops: the crate is built for baseline x86-64 (SSE2), so
//! the few loops that dominate (sparse block products, triangular solves, the reduced
//! Hessian's combine step) are compiled a second time with AVX2 + FMA and chosen when the CPU
//! has them. The two versions give identical results (the loops are plain sums; LLVM does
//! not fuse multiply-adds on its own). The reduced energy kernel (`sim::lanes`) uses the same
//! check but dispatches itself, since its fast version also switches to `mul_add`.

/// True when the CPU has AVX2 and FMA (x86-64; the standard library caches the check).
#[inline]
pub(crate) fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Define a free function whose body is compiled twice, for baseline x86-64 and with
/// AVX2 + FMA, and dispatched at run time with [`avx2_fma`]. No return value (results go
/// through `&mut` arguments).
macro_rules! multiversion {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn generic($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            unsafe fn avx2($($arg: $ty),*) {
                generic($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            {
                if $crate::simd::avx2_fma() {
                    // SAFETY: the CPU has the features `avx2` is compiled for.
                    return unsafe { avx2($($arg),*) };
                }
            }
            generic($($arg),*)
        }
    };
}
pub(crate) use multiversion;

/// Ask the CPU to bring `data[index]`'s cache line into its caches ahead of use (a hint with
/// no effect on results; nothing when `index` is out of range or off x86-64). For loops that
/// jump through memory in an order the hardware prefetcher cannot guess.
#[inline(always)]
pub(crate) fn prefetch<T>(data: &[T], index: usize) {
    if let Some(item) = data.get(index) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a prefetch never faults and reads nothing into the program; SSE, which it
        // needs, is part of baseline x86-64.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>((item as *const T).cast::<i8>());
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = item;
    }
}
