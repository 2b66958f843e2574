/* freeform C API example: gradients through a recorded run (docs/gradients.md). Opens a scene
 * file, records STEPS steps (argv[2], default 6), and takes the reverse pass of
 *
 *   L = sum over frames t = 0..T and objects i of the y of object i's first 4 rest points,
 *
 * whose dL/dz per frame comes from ff_world_positions_adjoint. Prints, one parseable line each:
 *
 *   loss L
 *   material I dL/dE dL/dnu
 *   gravity I dL/dgx dL/dgy dL/dgz        (objects with gravity)
 *   state I dL/dz0 . 1  dL/dzdot0 . 1     (the sums of the start state's gradients)
 *   collider I C dL/dmu dL/dkappa
 *   pair A B dL/dkappa dL/dmu              (scenes with [contact], A < B)
 *
 *   cargo build --release -p freeform-capi
 *   cc examples/gradient.c -Iffi/include target/release/libfreeform_capi.a -lm -lpthread -ldl \
 *      -o gradient && ./gradient examples/stack.toml 20
 *
 * Exits 1 on failure. `cargo test -p freeform-capi` runs it on two blocks in contact and
 * compares every number with the Rust API's for the same scene. */
#include <stdio.h>
#include <stdlib.h>

#include "freeform.h"

#define POINTS 4

static int fail(const char *what, int rc) {
    fprintf(stderr, "%s failed (%d): %s\n", what, rc, ff_last_error());
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s scene.toml [steps]\n", argv[0]);
        return 1;
    }
    size_t steps = argc > 2 ? (size_t)atoi(argv[2]) : 6;
    ff_world *w = NULL;
    int rc = ff_world_open(argv[1], 0, &w);
    if (rc != FF_OK) return fail("ff_world_open", rc);
    size_t n = ff_world_object_count(w);
    size_t colliders = ff_world_collider_count(w);

    /* Each object's first POINTS rest points and dL/dx = (0, 1, 0) at each. */
    double *rest = calloc(3 * POINTS * n, sizeof(double));
    double dl_dx[3 * POINTS];
    for (size_t p = 0; p < POINTS; p++) {
        dl_dx[3 * p] = 0.0;
        dl_dx[3 * p + 1] = 1.0;
        dl_dx[3 * p + 2] = 0.0;
    }
    for (size_t i = 0; i < n; i++) {
        size_t count = ff_world_point_count(w, i);
        double *all = malloc(3 * count * sizeof(double));
        rc = ff_world_rest_positions(w, i, all, 3 * count);
        if (rc != FF_OK) return fail("ff_world_rest_positions", rc);
        for (size_t k = 0; k < 3 * POINTS; k++) rest[3 * POINTS * i + k] = all[k];
        free(all);
    }

    /* The loss's value: the y of the points at every frame, the start included. */
    double loss = 0.0, x[3 * POINTS];
    ff_recording *rec = NULL;
    rc = ff_recording_start(w, steps, &rec);
    if (rc != FF_OK) return fail("ff_recording_start", rc);
    for (size_t t = 0; t <= steps; t++) {
        if (t > 0 && (rc = ff_recording_step(rec, w)) != FF_OK) return fail("ff_recording_step", rc);
        for (size_t i = 0; i < n; i++) {
            rc = ff_world_map_points(w, i, rest + 3 * POINTS * i, POINTS, x, 3 * POINTS);
            if (rc != FF_OK) return fail("ff_world_map_points", rc);
            for (size_t p = 0; p < POINTS; p++) loss += x[3 * p + 1];
        }
    }
    printf("loss %.17g\n", loss);

    /* dL/dz per frame: the same row at every frame (the map is linear in z). */
    double **dl_dz = malloc(n * sizeof(double *));
    for (size_t i = 0; i < n; i++) {
        size_t len = ff_world_state_len(w, i);
        dl_dz[i] = malloc((steps + 1) * len * sizeof(double));
        rc = ff_world_positions_adjoint(w, i, rest + 3 * POINTS * i, POINTS, dl_dx, dl_dz[i], len);
        if (rc != FF_OK) return fail("ff_world_positions_adjoint", rc);
        for (size_t t = 1; t <= steps; t++)
            for (size_t k = 0; k < len; k++) dl_dz[i][t * len + k] = dl_dz[i][k];
    }
    ff_gradients *g = NULL;
    rc = ff_recording_backward(rec, w, (const double *const *)dl_dz, n, &g);
    if (rc != FF_OK) return fail("ff_recording_backward", rc);

    for (size_t i = 0; i < n; i++) {
        double out[3];
        if ((rc = ff_gradients_material(g, i, out)) != FF_OK) return fail("material", rc);
        printf("material %zu %.17g %.17g\n", i, out[0], out[1]);
        if (ff_gradients_gravity(g, i, out) == FF_OK)
            printf("gravity %zu %.17g %.17g %.17g\n", i, out[0], out[1], out[2]);
        size_t len = ff_world_state_len(w, i);
        double *z0 = malloc(len * sizeof(double)), *v0 = malloc(len * sizeof(double));
        if ((rc = ff_gradients_state(g, i, z0, v0, len)) != FF_OK) return fail("state", rc);
        double sz = 0.0, sv = 0.0;
        for (size_t k = 0; k < len; k++) {
            sz += z0[k];
            sv += v0[k];
        }
        printf("state %zu %.17g %.17g\n", i, sz, sv);
        free(z0);
        free(v0);
        for (size_t c = 0; c < colliders; c++) {
            if ((rc = ff_gradients_collider(g, i, c, out)) != FF_OK) return fail("collider", rc);
            printf("collider %zu %zu %.17g %.17g\n", i, c, out[0], out[1]);
        }
        for (size_t b = i + 1; b < n; b++)
            if (ff_gradients_contact_pair(g, i, b, out) == FF_OK)
                printf("pair %zu %zu %.17g %.17g\n", i, b, out[0], out[1]);
    }
    ff_gradients_free(g);
    ff_recording_free(rec);
    for (size_t i = 0; i < n; i++) free(dl_dz[i]);
    free(dl_dz);
    free(rest);
    ff_world_free(w);
    return 0;
}
