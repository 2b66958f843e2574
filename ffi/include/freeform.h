/*
 * freeform C API: skinning eigenmodes from RKPM kernels (mesh-free reduced-order elasticity).
 *
 * Library: libfreeform_capi.so / libfreeform_capi.a, built by
 *     cargo build --release -p freeform-capi
 * Link:    cc app.c -Iffi/include -Ltarget/release -lfreeform_capi -lm
 * Guide:   docs/c-api.md. Example: examples/basis.c.
 *
 * Conventions
 *   - Every function returning int returns FF_OK (0) or an FF_ERR_* code; then
 *     ff_last_error() gives the message (per thread, valid until the next failure there).
 *   - Arrays are row-major doubles; lengths are element counts (size_t). Output arrays come
 *     with their capacity; a too small one gives FF_ERR_BUFFER_TOO_SMALL.
 *   - Units: positions in metres, volumes in m^3, Young's modulus in Pa, density in kg/m^3;
 *     eigenvalues in Pa/m^2.
 *   - Functions are thread-safe on distinct bases; a basis may be read from several threads.
 */
#ifndef FREEFORM_H
#define FREEFORM_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

enum {
    FF_OK = 0,
    FF_ERR_NULL_POINTER = 1,      /* a required pointer was NULL */
    FF_ERR_INVALID_ARGUMENT = 2,  /* a parameter or array is invalid (ranges, NaN, sizes) */
    FF_ERR_COVERAGE = 3,          /* points not covered by enough kernels */
    FF_ERR_EIGENSOLVER = 4,       /* the eigensolver failed or did not converge */
    FF_ERR_BUFFER_TOO_SMALL = 5,  /* an output array is too small */
    FF_ERR_PANIC = 6              /* internal error (caught); please report it */
};

/* Options of ff_basis_build; fill with ff_options_default, then change fields. */
typedef struct ff_options {
    size_t kernels;          /* number of RKPM kernels K (default 1000) */
    size_t modes;            /* non-constant modes m; m + 1 are computed (default 16) */
    int kernel;              /* 0 cubic B-spline (default), 1 quartic, 2 Gaussian */
    double support_factor;   /* support radius = factor x distance to the n-th neighbour (2.0) */
    size_t support_neighbor; /* that n (4) */
    double tol;              /* eigen residual tolerance (1e-8) */
    size_t max_iter;         /* eigensolver iteration cap (1000) */
    int solver;              /* 0 native LOBPCG (default), 1 dense (K up to a few thousand) */
} ff_options;

/* An opaque skinning basis: kernels, coefficients, eigenvalues. */
typedef struct ff_basis ff_basis;

/* Message of the last failure on this thread ("" if none). Do not free. */
const char *ff_last_error(void);

/* Fill *out with the default options. */
int ff_options_default(ff_options *out);

/* Build a basis from n integration points: points (n x 3), volumes (n), and per-point
 * youngs (n, Pa), poisson (n), density (n, kg/m^3). On success *out owns a basis; release it
 * with ff_basis_free. */
int ff_basis_build(const double *points, const double *volumes, const double *youngs,
                   const double *poisson, const double *density, size_t n,
                   const ff_options *options, ff_basis **out);

/* Release a basis (NULL is ignored). */
void ff_basis_free(ff_basis *basis);

/* Number of kernels K; number of modes m + 1 (constant mode included). 0 for NULL. */
size_t ff_basis_kernels(const ff_basis *basis);
size_t ff_basis_modes(const ff_basis *basis);

/* The m + 1 eigenvalues, ascending (the first ~0: constant mode), into out[len >= m + 1]. */
int ff_basis_eigenvalues(const ff_basis *basis, double *out, size_t len);

/* Coefficients c, K x (m + 1) row-major (out[k * (m + 1) + j]), M-orthonormal. */
int ff_basis_coefficients(const ff_basis *basis, double *out, size_t len);

/* Kernel centres, K x 3. */
int ff_basis_centers(const ff_basis *basis, double *out, size_t len);

/* Weights W_j at nq query points (queries: nq x 3) into weights[i * (m + 1) + j]
 * (weights_len >= nq (m + 1)); if gradients is not NULL, grad W_j into
 * gradients[(i * (m + 1) + j) * 3 + d] (gradients_len >= 3 nq (m + 1)). Query points must be
 * covered by the kernels (inside or near the sampled object), else FF_ERR_COVERAGE. */
int ff_basis_weights(const ff_basis *basis, const double *queries, size_t nq, double *weights,
                     size_t weights_len, double *gradients, size_t gradients_len);

#ifdef __cplusplus
}
#endif

#endif /* FREEFORM_H */
