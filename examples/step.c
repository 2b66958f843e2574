/* freeform C API example: the live simulation. Opens examples/step.toml (a soft bar held at
 * one end above a floor), steps it 30 times, and between steps twists and lifts the held end
 * (ff_world_set_boundary_pose), raises the floor (ff_world_set_collider_pose) and, for the
 * last 10 steps, turns gravity off. Prints parseable lines:
 *
 *   step K time T iterations I converged C contacts N
 *   points K I X Y Z       (every 10 steps: render points 0, N/2, N-1; metres)
 *   mean K X Y Z           (every 10 steps: the mean of the render points; metres)
 *
 * then restores the state saved after step 10, checks the positions are those of step 10,
 * and shows three error paths (bad index, small buffer, a reflection as a "rotation").
 *
 *   cargo build --release -p freeform-capi
 *   cc examples/step.c -Iffi/include target/release/libfreeform_capi.a -lm -lpthread -ldl \
 *      -o step && ./step examples/step.toml
 *
 * Exits 1 on failure. `cargo test -p freeform-capi` runs it and compares every number with
 * the same calls made on the Rust freeform::scene::World. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "freeform.h"

#define STEPS 30
#define PI 3.14159265358979323846

/* Print the failed call's code and message, free the world, exit 1. */
static int die(ff_world *w, const char *what, int rc) {
    fprintf(stderr, "%s failed (%d): %s\n", what, rc, ff_last_error());
    ff_world_free(w);
    return 1;
}

/* Mean of n points (n x 3) into m[3]. */
static void mean(const double *x, size_t n, double m[3]) {
    for (int d = 0; d < 3; d++) m[d] = 0.0;
    for (size_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) m[d] += x[3 * i + d];
    for (int d = 0; d < 3; d++) m[d] /= (double)n;
}

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "examples/step.toml";
    ff_world *w = NULL;
    int rc = ff_world_open(path, 0, &w);
    if (rc != FF_OK) return die(w, "ff_world_open", rc);

    size_t bar;
    rc = ff_world_object_index(w, "bar", &bar);
    if (rc != FF_OK) return die(w, "ff_world_object_index", rc);
    size_t n = ff_world_point_count(w, bar), len = ff_world_state_len(w, bar);
    printf("objects %zu colliders %zu boundaries %zu points %zu state %zu dt %.17g\n",
           ff_world_object_count(w), ff_world_collider_count(w), ff_world_boundary_count(w, bar),
           n, len, ff_world_dt(w));
    double *x = malloc(3 * n * sizeof(double));
    double *z = malloc(len * sizeof(double)), *zdot = malloc(len * sizeof(double));
    double *x10 = malloc(3 * n * sizeof(double));
    if (!x || !z || !zdot || !x10) return die(w, "malloc", -1);

    for (int k = 1; k <= STEPS; k++) {
        /* The held end: twisted by k degrees about the bar's axis (the line y = z = 0.1 m)
         * and lifted by 2 mm per step: x = R X + t with t = p - R p + lift. */
        const double a = k * PI / 180.0, c = cos(a), s = sin(a);
        const double R[9] = {1, 0, 0, 0, c, -s, 0, s, c};
        const double p[3] = {0.0, 0.1, 0.1};
        double t[3];
        for (int i = 0; i < 3; i++)
            t[i] = p[i] - (R[3 * i] * p[0] + R[3 * i + 1] * p[1] + R[3 * i + 2] * p[2]);
        t[1] += 0.002 * k;
        rc = ff_world_set_boundary_pose(w, bar, 0, R, t);
        if (rc != FF_OK) return die(w, "ff_world_set_boundary_pose", rc);
        /* The floor rises by 3 mm per step (a kinematic obstacle: poses are absolute). */
        const double lift[3] = {0.0, 0.003 * k, 0.0};
        rc = ff_world_set_collider_pose(w, 0, NULL, lift);
        if (rc != FF_OK) return die(w, "ff_world_set_collider_pose", rc);
        if (k == STEPS - 9) {
            rc = ff_world_set_gravity(w, NULL);
            if (rc != FF_OK) return die(w, "ff_world_set_gravity", rc);
        }

        rc = ff_world_step(w);
        if (rc != FF_OK) return die(w, "ff_world_step", rc);
        ff_step_report rep;
        rc = ff_world_step_report(w, bar, &rep);
        if (rc != FF_OK) return die(w, "ff_world_step_report", rc);
        printf("step %zu time %.17g iterations %zu converged %d contacts %zu\n", rep.step,
               ff_world_time(w), rep.iterations, rep.converged, rep.contacts);

        if (k % 10 == 0) {
            rc = ff_world_positions(w, bar, x, 3 * n);
            if (rc != FF_OK) return die(w, "ff_world_positions", rc);
            const size_t show[3] = {0, n / 2, n - 1};
            for (int j = 0; j < 3; j++) {
                const double *q = x + 3 * show[j];
                printf("points %d %zu %.17g %.17g %.17g\n", k, show[j], q[0], q[1], q[2]);
            }
            double m[3];
            mean(x, n, m);
            printf("mean %d %.17g %.17g %.17g\n", k, m[0], m[1], m[2]);
        }
        if (k == 10) {
            rc = ff_world_get_state(w, bar, z, zdot, len);
            if (rc != FF_OK) return die(w, "ff_world_get_state", rc);
            memcpy(x10, x, 3 * n * sizeof(double));
        }
    }
    printf("nonconverged %zu warnings %zu\n", ff_world_nonconverged_steps(w, bar),
           ff_world_warning_count(w));
    for (size_t i = 0; i < ff_world_warning_count(w); i++)
        printf("warning: %s\n", ff_world_warning(w, i));

    /* Positions depend on the state only: restoring step 10's gives step 10's positions. */
    rc = ff_world_set_state(w, bar, z, zdot, len);
    if (rc != FF_OK) return die(w, "ff_world_set_state", rc);
    rc = ff_world_positions(w, bar, x, 3 * n);
    if (rc != FF_OK) return die(w, "ff_world_positions", rc);
    int restored = memcmp(x, x10, 3 * n * sizeof(double)) == 0;
    printf("restored %s\n", restored ? "yes" : "no");

    /* Errors are codes with messages, never crashes. */
    rc = ff_world_positions(w, 7, x, 3 * n);
    printf("bad object: code %d: %s\n", rc, ff_last_error());
    int ok = restored && rc == FF_ERR_INVALID_ARGUMENT;
    rc = ff_world_positions(w, bar, x, 3);
    printf("small buffer: code %d: %s\n", rc, ff_last_error());
    ok = ok && rc == FF_ERR_BUFFER_TOO_SMALL;
    const double mirror[9] = {1, 0, 0, 0, 1, 0, 0, 0, -1}, zero[3] = {0, 0, 0};
    rc = ff_world_set_boundary_pose(w, bar, 0, mirror, zero);
    printf("reflection: code %d: %s\n", rc, ff_last_error());
    ok = ok && rc == FF_ERR_INVALID_ARGUMENT;

    ff_world_free(w);
    free(x);
    free(x10);
    free(z);
    free(zdot);
    printf("%s\n", ok ? "OK" : "FAILED");
    return ok ? 0 : 1;
}
