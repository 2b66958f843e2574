/* The eigensolver over your own operators from C: the Q1 finite-element Laplacian (stiffness
 * and consistent mass) on a 7 x 8 x 9 node grid, h = 0.1 m, applied by an element loop here,
 * never assembled; ff_eigen_solve_operators finds its 8 smallest pairs. Then two failing
 * callbacks show the errors. Prints "lambda <value>" lines, then "error <code>: <message>".
 *
 *   cargo build --release -p freeform-capi
 *   cc examples/operators.c -Iffi/include target/release/libfreeform_capi.a -lm -lpthread -ldl
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "freeform.h"

enum { NX = 7, NY = 8, NZ = 9, K = NX * NY * NZ, NEV = 8 };
static const double H = 0.1;

/* An 8 x 8 element matrix and a flag for the diagonal pass. */
typedef struct {
    double e[8][8];
} element;

static element make_element(int stiffness) {
    const double k1[2][2] = {{1.0 / H, -1.0 / H}, {-1.0 / H, 1.0 / H}};
    const double m1[2][2] = {{H / 3.0, H / 6.0}, {H / 6.0, H / 3.0}};
    element el;
    for (int l = 0; l < 8; l++) {
        for (int r = 0; r < 8; r++) {
            int a = l & 1, b = (l >> 1) & 1, c = l >> 2;
            int ap = r & 1, bp = (r >> 1) & 1, cp = r >> 2;
            double mass = m1[a][ap] * m1[b][bp] * m1[c][cp];
            el.e[l][r] = stiffness ? k1[a][ap] * m1[b][bp] * m1[c][cp] +
                                         m1[a][ap] * k1[b][bp] * m1[c][cp] +
                                         m1[a][ap] * m1[b][bp] * k1[c][cp]
                                   : mass;
        }
    }
    return el;
}

/* y = A x column by column, gathering and scattering the 8 nodes of every element. */
static int apply(void *ctx, const double *x, double *y, size_t k, size_t ncols) {
    const element *el = ctx;
    for (size_t j = 0; j < ncols; j++) {
        const double *xj = x + j * k;
        double *yj = y + j * k;
        for (size_t i = 0; i < k; i++) yj[i] = 0.0;
        for (int ez = 0; ez < NZ - 1; ez++)
            for (int ey = 0; ey < NY - 1; ey++)
                for (int ex = 0; ex < NX - 1; ex++) {
                    size_t node[8];
                    for (int l = 0; l < 8; l++)
                        node[l] = (size_t)((ex + (l & 1)) +
                                           NX * ((ey + ((l >> 1) & 1)) + NY * (ez + (l >> 2))));
                    for (int l = 0; l < 8; l++) {
                        double s = 0.0;
                        for (int r = 0; r < 8; r++) s += el->e[l][r] * xj[node[r]];
                        yj[node[l]] += s;
                    }
                }
    }
    return 0;
}

static void diagonal(const element *el, double *d) {
    for (size_t i = 0; i < K; i++) d[i] = 0.0;
    for (int ez = 0; ez < NZ - 1; ez++)
        for (int ey = 0; ey < NY - 1; ey++)
            for (int ex = 0; ex < NX - 1; ex++)
                for (int l = 0; l < 8; l++)
                    d[(ex + (l & 1)) + NX * ((ey + ((l >> 1) & 1)) + NY * (ez + (l >> 2)))] +=
                        el->e[l][l];
}

static int failing(void *ctx, const double *x, double *y, size_t k, size_t ncols) {
    (void)ctx, (void)x, (void)y, (void)k, (void)ncols;
    ff_callback_error("device lost");
    return 3;
}

/* Writes only the first column: the rest stays NaN and is caught. */
static int short_write(void *ctx, const double *x, double *y, size_t k, size_t ncols) {
    (void)ncols;
    return apply(ctx, x, y, k, 1);
}

int main(void) {
    element stiffness = make_element(1), mass = make_element(0);
    static double hd[K], md[K], values[NEV], vectors[K * NEV];
    diagonal(&stiffness, hd);
    diagonal(&mass, md);
    size_t iterations = 0;
    int rc = ff_eigen_solve_operators(K, NEV, 1e-9, 2000, apply, &stiffness, apply, &mass, NULL,
                                      NULL, hd, md, values, vectors, &iterations);
    if (rc != FF_OK) {
        fprintf(stderr, "solve failed: %s\n", ff_last_error());
        return 1;
    }
    printf("iterations %zu\n", iterations);
    for (int i = 0; i < NEV; i++) printf("lambda %.17g\n", values[i]);
    rc = ff_eigen_solve_operators(K, NEV, 1e-9, 2000, apply, &stiffness, failing, NULL, NULL,
                                  NULL, NULL, NULL, values, vectors, NULL);
    printf("error %d: %s\n", rc, ff_last_error());
    rc = ff_eigen_solve_operators(K, NEV, 1e-9, 2000, short_write, &stiffness, apply, &mass,
                                  NULL, NULL, NULL, NULL, values, vectors, NULL);
    printf("error %d: %s\n", rc, ff_last_error());
    return 0;
}
