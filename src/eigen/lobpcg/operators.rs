//! H and M as the iteration applies them to column ranges of its row-major blocks. An
//! assembled matrix goes through the row-major sparse kernels (and H and M together through
//! the fused pair kernel, one pass over the shared pattern): the historic path, bit for bit.
//! Anything else goes through [`apply_checked`] on views of the blocks, so a caller's operator
//! is checked for shape, error and finite output on every application. Matrices stored as
//! upper triangles of one pattern go through `crate::triangle`'s kernels (H and M together in
//! one pass too).

use super::workspace::Block;
use crate::eigen::{apply_checked, EigenError, LinearOperator};
use crate::sparse;
use crate::triangle::{self, UpperRef};

/// Which of the two operators.
#[derive(Clone, Copy)]
pub(super) enum Which {
    H,
    M,
}

/// H and M with their 1-norms (exact for assembled matrices, estimated otherwise).
pub(super) struct Operators<'a> {
    h: &'a dyn LinearOperator,
    m: &'a dyn LinearOperator,
    /// Both assembled with one pattern (checked once here, not at every product).
    shared: Option<sparse::SharedPattern<'a>>,
    /// Both stored as upper triangles of one pattern.
    upper: Option<(UpperRef<'a>, UpperRef<'a>)>,
    pub norm_h: f64,
    pub norm_m: f64,
}

/// H and M as upper triangles of one pattern, when both are held so (a pair of triangles
/// with two patterns is applied as operators).
pub(super) fn upper_pair<'a>(
    h: &'a dyn LinearOperator,
    m: &'a dyn LinearOperator,
) -> Option<(UpperRef<'a>, UpperRef<'a>)> {
    h.upper_triangle()
        .zip(m.upper_triangle())
        .filter(|(a, b)| a.same_pattern(b))
}

impl<'a> Operators<'a> {
    pub fn new(
        h: &'a dyn LinearOperator,
        m: &'a dyn LinearOperator,
        norm_h: f64,
        norm_m: f64,
    ) -> Self {
        let shared = match (h.assembled(), m.assembled()) {
            (Some(a), Some(b)) => sparse::SharedPattern::new(a, b),
            _ => None,
        };
        let upper = upper_pair(h, m);
        Self {
            h,
            m,
            shared,
            upper,
            norm_h,
            norm_m,
        }
    }

    /// Global size K.
    pub fn dim(&self) -> usize {
        self.h.dim()
    }

    fn op(&self, which: Which) -> (&'a dyn LinearOperator, &'static str) {
        match which {
            Which::H => (self.h, "H"),
            Which::M => (self.m, "M"),
        }
    }

    /// Columns `c0..c0 + w` of `out` = A times the same columns of `s`.
    pub fn apply(
        &self,
        which: Which,
        s: &Block,
        out: &mut Block,
        c0: usize,
        w: usize,
    ) -> Result<(), EigenError> {
        let (op, name) = self.op(which);
        if let Some(a) = op.upper_triangle() {
            a.mul_row_major(&s.data[c0..], s.ld, &mut out.data[c0..], out.ld, w);
            return Ok(());
        }
        match op.assembled() {
            Some(a) => {
                sparse::sym_mul_row_major(a, &s.data[c0..], s.ld, &mut out.data[c0..], out.ld, w);
                Ok(())
            }
            None => apply_checked(op, name, s.cols(c0, w), out.cols_mut(c0, w)),
        }
    }

    /// H S and M S for the columns `c0..c0 + w`, in one pass when both are assembled.
    pub fn apply_both(
        &self,
        s: &Block,
        hs: &mut Block,
        ms: &mut Block,
        c0: usize,
        w: usize,
    ) -> Result<(), EigenError> {
        if let Some(pair) = &self.shared {
            debug_assert_eq!(hs.ld, ms.ld);
            pair.mul_row_major(
                &s.data[c0..],
                s.ld,
                &mut hs.data[c0..],
                &mut ms.data[c0..],
                hs.ld,
                w,
            );
            return Ok(());
        }
        if let Some((a, b)) = self.upper {
            debug_assert_eq!(hs.ld, ms.ld);
            triangle::mul_pair_row_major(
                a,
                b,
                &s.data[c0..],
                s.ld,
                &mut hs.data[c0..],
                &mut ms.data[c0..],
                hs.ld,
                w,
            );
            return Ok(());
        }
        self.apply(Which::H, s, hs, c0, w)?;
        self.apply(Which::M, s, ms, c0, w)
    }
}
