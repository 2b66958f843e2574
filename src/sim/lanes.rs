//! The elastic energy and gradient kernel, vectorized across points: cubature points are
//! stored in blocks of [`LANES`] (structure of arrays), so the per-handle updates of F and of
//! the gradient run as SIMD loops over the lanes. On x86-64 the kernel is compiled a second
//! time with AVX2 + FMA and chosen at run time when the CPU has them; that version fuses the
//! multiply-adds (`mul_add`, which Rust never forms on its own: 1.45x faster on one core at
//! m = 32), the portable one keeps plain products (`mul_add` without hardware FMA is a slow
//! library call).

use crate::Point3;

/// Points per block.
pub const LANES: usize = 8;

type Lane = [f64; LANES];

/// A 3 x 3 matrix per lane of a block: m[r][c][lane].
pub type LaneMat = [[Lane; 3]; 3];

/// F and its cofactor matrix at one state, per block ([`LaneData::deformation_gradient_blocks`]):
/// what every Hessian product at that state reuses.
#[derive(Debug, Clone)]
pub struct BlockState {
    f: LaneMat,
    cof: LaneMat,
}

/// Cubature data in blocks of LANES points; padding lanes have zero volume and zero weights.
#[derive(Debug, Clone)]
pub struct LaneData {
    handles: usize,
    len: usize,
    /// Rest positions per block: x[block][c][lane].
    x: Vec<[Lane; 3]>,
    vol: Vec<Lane>,
    lambda: Vec<Lane>,
    mu: Vec<Lane>,
    /// W_j per block: w[block * handles + j][lane].
    w: Vec<Lane>,
    /// grad W_j per block: gw[block * handles + j][c][lane].
    gw: Vec<[Lane; 3]>,
}

/// Result of one block range: energy, min det F, inverted count.
#[derive(Debug, Clone, Copy)]
pub struct Partial {
    /// Energy, J.
    pub energy: f64,
    /// Smallest det F among real (non-padding) points.
    pub min_det: f64,
    /// Real points with det F <= 0.
    pub inverted: usize,
}

impl LaneData {
    /// Pack per-point arrays (weights row-major by point, `handles` per point).
    pub fn new(
        points: &[Point3],
        volumes: &[f64],
        lambda: &[f64],
        mu: &[f64],
        w: &[f64],
        gw: &[[f64; 3]],
        handles: usize,
    ) -> LaneData {
        let n = points.len();
        let nb = n.div_ceil(LANES);
        let mut d = LaneData {
            handles,
            len: n,
            x: vec![[[0.0; LANES]; 3]; nb],
            vol: vec![[0.0; LANES]; nb],
            // Padding lanes get a valid material so Psi stays finite (and is multiplied by 0).
            lambda: vec![[1.0; LANES]; nb],
            mu: vec![[1.0; LANES]; nb],
            w: vec![[0.0; LANES]; nb * handles],
            gw: vec![[[0.0; LANES]; 3]; nb * handles],
        };
        for i in 0..n {
            let (b, l) = (i / LANES, i % LANES);
            for c in 0..3 {
                d.x[b][c][l] = points[i][c];
            }
            d.vol[b][l] = volumes[i];
            d.lambda[b][l] = lambda[i];
            d.mu[b][l] = mu[i];
            for j in 0..handles {
                d.w[b * handles + j][l] = w[i * handles + j];
                for c in 0..3 {
                    d.gw[b * handles + j][c][l] = gw[i * handles + j][c];
                }
            }
        }
        d
    }

    /// Number of blocks.
    pub fn blocks(&self) -> usize {
        self.vol.len()
    }

    /// Energy of blocks `range`, with the gradient added to `grad` when given.
    pub fn eval(
        &self,
        range: std::ops::Range<usize>,
        z: &[f64],
        grad: Option<&mut [f64]>,
    ) -> Partial {
        #[cfg(target_arch = "x86_64")]
        {
            if crate::simd::avx2_fma() {
                // SAFETY: the CPU supports the features the function is compiled for.
                return unsafe { self.eval_avx2(range, z, grad) };
            }
        }
        self.eval_generic::<Plain>(range, z, grad)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eval_avx2(
        &self,
        range: std::ops::Range<usize>,
        z: &[f64],
        grad: Option<&mut [f64]>,
    ) -> Partial {
        self.eval_generic::<Fused>(range, z, grad)
    }

    /// F of the LANES points of block `b`: f[r][c][lane].
    #[inline(always)]
    ///
    /// Written with an out-parameter and plain indexing: returning the array by value or
    /// destructuring it kept LLVM from vectorizing the lane loop (measured).
    fn deformation_gradients<M: MulAdd>(&self, b: usize, z: &[f64], f: &mut [[Lane; 3]; 3]) {
        self.deformation_map::<M>(b, z, 1.0, f);
    }

    /// `diagonal` I + (dF/dz) z of block `b` (F for 1, its change along z for 0: without the
    /// identity, so a small change keeps its relative precision).
    #[inline(always)]
    fn deformation_map<M: MulAdd>(
        &self,
        b: usize,
        z: &[f64],
        diagonal: f64,
        f: &mut [[Lane; 3]; 3],
    ) {
        let nh = self.handles;
        let n4 = 4 * nh;
        let x = &self.x[b];
        *f = [[[0.0; LANES]; 3]; 3];
        for r in 0..3 {
            f[r][r] = [diagonal; LANES];
            let fr = &mut f[r];
            for j in 0..nh {
                let w = &self.w[b * nh + j];
                let g = &self.gw[b * nh + j];
                let o = r * n4 + 4 * j;
                let (z0, z1, z2, z3) = (z[o], z[o + 1], z[o + 2], z[o + 3]);
                for l in 0..LANES {
                    let y = M::mul_add(
                        z0,
                        x[0][l],
                        M::mul_add(z1, x[1][l], M::mul_add(z2, x[2][l], z3)),
                    );
                    fr[0][l] = M::mul_add(g[0][l], y, M::mul_add(w[l], z0, fr[0][l]));
                    fr[1][l] = M::mul_add(g[1][l], y, M::mul_add(w[l], z1, fr[1][l]));
                    fr[2][l] = M::mul_add(g[2][l], y, M::mul_add(w[l], z2, fr[2][l]));
                }
            }
        }
    }

    /// Lane-wise v Psi(F) (into `e`), det F and v P(F) (into `p`) of block `b`:
    /// Psi = mu/2 (|F|^2 - 3) + (lambda + mu)/2 ((J - gamma)^2 - (1 - gamma)^2),
    /// P = mu F + (lambda + mu)(J - gamma) cof F (see [`crate::elasticity`]).
    #[inline(always)]
    fn stress(
        &self,
        b: usize,
        f: &[[Lane; 3]; 3],
        p: &mut [[Lane; 3]; 3],
        det: &mut Lane,
        e: &mut Lane,
    ) {
        let (lam, mu, vol) = (&self.lambda[b], &self.mu[b], &self.vol[b]);
        let mut cof = [[[0.0; LANES]; 3]; 3];
        cofactors(f, &mut cof);
        for l in 0..LANES {
            let j =
                f[0][0][l] * cof[0][0][l] + f[0][1][l] * cof[0][1][l] + f[0][2][l] * cof[0][2][l];
            let mut tr = 0.0;
            for r in 0..3 {
                for c in 0..3 {
                    tr += f[r][c][l] * f[r][c][l];
                }
            }
            let lm = lam[l] + mu[l];
            let gamma = 1.0 + mu[l] / lm;
            let (dj, d1) = (j - gamma, 1.0 - gamma);
            det[l] = j;
            e[l] = vol[l] * (0.5 * mu[l] * (tr - 3.0) + 0.5 * lm * (dj * dj - d1 * d1));
            let sv = vol[l] * lm * dj;
            let mv = vol[l] * mu[l];
            for r in 0..3 {
                for c in 0..3 {
                    p[r][c][l] = mv * f[r][c][l] + sv * cof[r][c][l];
                }
            }
        }
    }

    #[inline(always)]
    fn eval_generic<M: MulAdd>(
        &self,
        range: std::ops::Range<usize>,
        z: &[f64],
        grad: Option<&mut [f64]>,
    ) -> Partial {
        let nh = self.handles;
        let mut out = Partial {
            energy: 0.0,
            min_det: f64::INFINITY,
            inverted: 0,
        };
        // Gradient accumulators per lane (summed across lanes once at the end).
        // acc[r * handles + j][a][lane] accumulates dE/dZ_j[r][a].
        let mut acc: Vec<[Lane; 4]> = if grad.is_some() {
            vec![[[0.0; LANES]; 4]; 3 * nh]
        } else {
            Vec::new()
        };
        let mut f = [[[0.0; LANES]; 3]; 3];
        let mut p = [[[0.0; LANES]; 3]; 3];
        for b in range {
            let x = &self.x[b];
            self.deformation_gradients::<M>(b, z, &mut f);
            // Psi and v P, lane-wise (the same formulas as crate::elasticity).
            let mut det = [0.0; LANES];
            let mut e = [0.0; LANES];
            self.stress(b, &f, &mut p, &mut det, &mut e);
            out.energy += e.iter().sum::<f64>();
            for (l, d) in det.iter().enumerate() {
                if b * LANES + l < self.len {
                    out.min_det = out.min_det.min(*d);
                    if *d <= 0.0 {
                        out.inverted += 1;
                    }
                }
            }
            if grad.is_none() {
                continue;
            }
            for j in 0..nh {
                let w = &self.w[b * nh + j];
                let gw = &self.gw[b * nh + j];
                for r in 0..3 {
                    let pr = &p[r];
                    accumulate::<M>(&mut acc[r * nh + j], pr, gw, w, x);
                }
            }
        }
        if let Some(g) = grad {
            // Flat index r * n4 + 4 j + a = 4 (r * handles + j) + a.
            for (gi, a) in g.chunks_exact_mut(4).zip(&acc) {
                for k in 0..4 {
                    gi[k] += a[k].iter().sum::<f64>();
                }
            }
        }
        out
    }
}

impl LaneData {
    /// F and cof F of every block at `z`, for [`LaneData::hessian_product`] (one per block).
    pub fn deformation_gradient_blocks(&self, z: &[f64]) -> Vec<BlockState> {
        #[cfg(target_arch = "x86_64")]
        {
            if crate::simd::avx2_fma() {
                // SAFETY: the CPU supports the features the function is compiled for.
                return unsafe { self.deformation_gradient_blocks_avx2(z) };
            }
        }
        self.deformation_gradient_blocks_generic::<Plain>(z)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn deformation_gradient_blocks_avx2(&self, z: &[f64]) -> Vec<BlockState> {
        self.deformation_gradient_blocks_generic::<Fused>(z)
    }

    #[inline(always)]
    fn deformation_gradient_blocks_generic<M: MulAdd>(&self, z: &[f64]) -> Vec<BlockState> {
        let zero = [[[0.0; LANES]; 3]; 3];
        let mut out = vec![BlockState { f: zero, cof: zero }; self.blocks()];
        for (b, state) in out.iter_mut().enumerate() {
            self.deformation_gradients::<M>(b, z, &mut state.f);
            cofactors(&state.f, &mut state.cof);
        }
        out
    }

    /// Add H(z) v of blocks `range` to `out` (12 (m + 1)): the elastic Hessian along `v`
    /// without forming it, as the gradient with v dP = v dP/dF : dF in place of v P; `f`
    /// holds F and cof F at z of every block ([`LaneData::deformation_gradient_blocks`]).
    pub fn hessian_product(
        &self,
        range: std::ops::Range<usize>,
        f: &[BlockState],
        v: &[f64],
        out: &mut [f64],
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if crate::simd::avx2_fma() {
                // SAFETY: the CPU supports the features the function is compiled for.
                return unsafe { self.hessian_product_avx2(range, f, v, out) };
            }
        }
        self.hessian_product_generic::<Plain>(range, f, v, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn hessian_product_avx2(
        &self,
        range: std::ops::Range<usize>,
        f: &[BlockState],
        v: &[f64],
        out: &mut [f64],
    ) {
        self.hessian_product_generic::<Fused>(range, f, v, out)
    }

    /// Lane-wise v dP of block `b` at the state `at` (F, cof F) along dF = `df`:
    /// dP = mu dF + (lambda + mu) ((cof F : dF) cof F + (J - gamma) dcof), with
    /// dcof the cofactor's derivative (each entry a difference of two 2 x 2 minors' changes).
    #[inline(always)]
    fn stress_change(&self, b: usize, at: &BlockState, df: &LaneMat, dp: &mut LaneMat) {
        let (lam, mu, vol) = (&self.lambda[b], &self.mu[b], &self.vol[b]);
        let (f, cof) = (&at.f, &at.cof);
        let mut dcof = [[[0.0; LANES]; 3]; 3];
        for r in 0..3 {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            for c in 0..3 {
                let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
                for l in 0..LANES {
                    dcof[r][c][l] = df[r1][c1][l] * f[r2][c2][l] + f[r1][c1][l] * df[r2][c2][l]
                        - df[r1][c2][l] * f[r2][c1][l]
                        - f[r1][c2][l] * df[r2][c1][l];
                }
            }
        }
        for l in 0..LANES {
            let j =
                f[0][0][l] * cof[0][0][l] + f[0][1][l] * cof[0][1][l] + f[0][2][l] * cof[0][2][l];
            let mut dj = 0.0;
            for r in 0..3 {
                for c in 0..3 {
                    dj += cof[r][c][l] * df[r][c][l];
                }
            }
            let lm = lam[l] + mu[l];
            let gamma = 1.0 + mu[l] / lm;
            let (a, sj, sc) = (vol[l] * mu[l], vol[l] * lm * dj, vol[l] * lm * (j - gamma));
            for r in 0..3 {
                for c in 0..3 {
                    dp[r][c][l] = a * df[r][c][l] + sj * cof[r][c][l] + sc * dcof[r][c][l];
                }
            }
        }
    }

    #[inline(always)]
    fn hessian_product_generic<M: MulAdd>(
        &self,
        range: std::ops::Range<usize>,
        f: &[BlockState],
        v: &[f64],
        out: &mut [f64],
    ) {
        let nh = self.handles;
        let mut acc: Vec<[Lane; 4]> = vec![[[0.0; LANES]; 4]; 3 * nh];
        let mut df = [[[0.0; LANES]; 3]; 3];
        let mut dp = [[[0.0; LANES]; 3]; 3];
        for b in range {
            let x = &self.x[b];
            // F is affine in z: its change along v is the linear part alone (not F(v) - I,
            // which would round a small v's diagonal to 1e-16 absolute).
            self.deformation_map::<M>(b, v, 0.0, &mut df);
            self.stress_change(b, &f[b], &df, &mut dp);
            for j in 0..nh {
                let w = &self.w[b * nh + j];
                let gw = &self.gw[b * nh + j];
                for r in 0..3 {
                    accumulate::<M>(&mut acc[r * nh + j], &dp[r], gw, w, x);
                }
            }
        }
        for (gi, a) in out.chunks_exact_mut(4).zip(&acc) {
            for k in 0..4 {
                gi[k] += a[k].iter().sum::<f64>();
            }
        }
    }
}

/// The cofactor matrix of `f`, lane-wise: each entry a 2 x 2 minor (row r of cof F is
/// row r + 1 x row r + 2 of F).
#[inline(always)]
fn cofactors(f: &LaneMat, cof: &mut LaneMat) {
    for r in 0..3 {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        for c in 0..3 {
            let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
            for l in 0..LANES {
                cof[r][c][l] = f[r1][c1][l] * f[r2][c2][l] - f[r1][c2][l] * f[r2][c1][l];
            }
        }
    }
}

/// a[k] += dF/dZ_j[r][k] : v P_r for one handle j and row r, lane-wise. A separate function
/// so the `&mut` accumulator is known not to alias the inputs (LLVM kept the loop scalar
/// when it was written inline).
#[inline(always)]
fn accumulate<M: MulAdd>(
    a: &mut [Lane; 4],
    pr: &[Lane; 3],
    gw: &[Lane; 3],
    w: &Lane,
    x: &[Lane; 3],
) {
    for l in 0..LANES {
        let pj = M::mul_add(
            pr[0][l],
            gw[0][l],
            M::mul_add(pr[1][l], gw[1][l], pr[2][l] * gw[2][l]),
        );
        a[0][l] = M::mul_add(pj, x[0][l], M::mul_add(w[l], pr[0][l], a[0][l]));
        a[1][l] = M::mul_add(pj, x[1][l], M::mul_add(w[l], pr[1][l], a[1][l]));
        a[2][l] = M::mul_add(pj, x[2][l], M::mul_add(w[l], pr[2][l], a[2][l]));
        a[3][l] += pj;
    }
}

/// a * b + c: fused ([`Fused`], one rounding) in the functions compiled with FMA, plain
/// ([`Plain`]) in the portable one (`mul_add` without hardware FMA is a slow library call).
trait MulAdd {
    fn mul_add(a: f64, b: f64, c: f64) -> f64;
}

/// Fused multiply-add.
struct Fused;

impl MulAdd for Fused {
    #[inline(always)]
    fn mul_add(a: f64, b: f64, c: f64) -> f64 {
        a.mul_add(b, c)
    }
}

/// Separate product and sum.
struct Plain;

impl MulAdd for Plain {
    #[inline(always)]
    fn mul_add(a: f64, b: f64, c: f64) -> f64 {
        a * b + c
    }
}
