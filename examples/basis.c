/* freeform C API example: skinning eigenmodes of a 2 x 1 x 1 m box sampled on a grid.
 *
 *   cargo build --release -p freeform-capi
 *   cc examples/basis.c -Iffi/include target/release/libfreeform_capi.a -lm -lpthread -ldl \
 *      -o basis && ./basis
 *
 * Prints the eigenvalues, then checks two exact properties: the constant mode's weight is
 * 1 / sqrt(volume) everywhere (c^T M c = 1), and its gradient is zero. Exits 1 on failure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "freeform.h"

int main(void) {
    const double h = 0.1; /* grid spacing, m: 20 x 10 x 10 cell centres */
    const size_t nx = 20, ny = 10, nz = 10, n = nx * ny * nz;
    double *points = malloc(3 * n * sizeof(double));
    double *volumes = malloc(n * sizeof(double));
    double *youngs = malloc(n * sizeof(double));
    double *poisson = malloc(n * sizeof(double));
    double *density = malloc(n * sizeof(double));
    if (!points || !volumes || !youngs || !poisson || !density) return 1;
    size_t p = 0;
    for (size_t k = 0; k < nz; k++)
        for (size_t j = 0; j < ny; j++)
            for (size_t i = 0; i < nx; i++, p++) {
                points[3 * p + 0] = (i + 0.5) * h;
                points[3 * p + 1] = (j + 0.5) * h;
                points[3 * p + 2] = (k + 0.5) * h;
                volumes[p] = h * h * h;
                youngs[p] = 5e6;
                poisson[p] = 0.45;
                density[p] = 1000.0;
            }

    ff_options opt;
    ff_options_default(&opt);
    opt.kernels = 120;
    opt.modes = 6;

    /* A bad call first: too few kernels is an error code with a message, not a crash. */
    ff_options bad = opt;
    bad.kernels = 2;
    ff_basis *basis = NULL;
    int rc = ff_basis_build(points, volumes, youngs, poisson, density, n, &bad, &basis);
    printf("bad options: code %d: %s\n", rc, ff_last_error());
    if (rc == FF_OK || basis != NULL) return 1;

    rc = ff_basis_build(points, volumes, youngs, poisson, density, n, &opt, &basis);
    if (rc != FF_OK) {
        fprintf(stderr, "ff_basis_build failed (%d): %s\n", rc, ff_last_error());
        return 1;
    }
    size_t K = ff_basis_kernels(basis), m = ff_basis_modes(basis);
    printf("kernels %zu modes %zu\n", K, m);
    double ev[64];
    if (m > 64 || ff_basis_eigenvalues(basis, ev, 64) != FF_OK) return 1;
    printf("eigenvalues");
    for (size_t j = 0; j < m; j++) printf(" %.12e", ev[j]);
    printf("\n");

    /* Weights and gradients at three points inside the box. */
    const double q[9] = {0.3, 0.5, 0.5, 1.0, 0.2, 0.7, 1.8, 0.9, 0.1};
    double w[3 * 64], g[3 * 3 * 64];
    rc = ff_basis_weights(basis, q, 3, w, 3 * m, g, 9 * m);
    if (rc != FF_OK) {
        fprintf(stderr, "ff_basis_weights failed (%d): %s\n", rc, ff_last_error());
        return 1;
    }
    double expect = 1.0 / sqrt(2.0), worst = 0.0, worst_grad = 0.0;
    for (size_t i = 0; i < 3; i++) {
        worst = fmax(worst, fabs(w[i * m] - expect));
        for (int d = 0; d < 3; d++) worst_grad = fmax(worst_grad, fabs(g[(i * m) * 3 + d]));
    }
    printf("constant mode: max |W_0 - 1/sqrt(V)| %.3e, max |grad W_0| %.3e\n", worst,
           worst_grad);
    /* A too small buffer is reported. */
    rc = ff_basis_weights(basis, q, 3, w, 1, NULL, 0);
    printf("small buffer: code %d: %s\n", rc, ff_last_error());
    ff_basis_free(basis);
    free(points);
    free(volumes);
    free(youngs);
    free(poisson);
    free(density);
    int ok = worst < 1e-8 && worst_grad < 1e-6 && rc == FF_ERR_BUFFER_TOO_SMALL;
    printf("%s\n", ok ? "OK" : "FAILED");
    return ok ? 0 : 1;
}
