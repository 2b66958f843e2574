/* freeform C API example: object-object contact reports. Opens a scene file, steps it STEPS
 * times (argv[2], default 10) and after each step prints the world's contact report
 * (ff_world_contact_report) as one parseable line:
 *
 *   contact K enabled E tested T near N active A penetration P fraction F islands I
 *     largest L regrouped R
 *
 * (one line; P in metres, F relative to the smaller rest diagonal of the two objects) and the
 * visible penetration (ff_world_visible_penetration: surface points, not samples)
 *
 *   visible K P F
 *
 * then
 *
 *   worst P F over S visible P F
 *
 * the run's worst penetration (metres, fraction), the steps above the tolerance and the run's
 * worst visible penetration. A scene without [contact] prints zeros (enabled 0).
 *
 *   cargo build --release -p freeform-capi
 *   cc examples/contact.c -Iffi/include target/release/libfreeform_capi.a -lm -lpthread -ldl \
 *      -o contact && ./contact examples/stack.toml 40
 *
 * Exits 1 on failure. `cargo test -p freeform-capi` runs it on a two-block scene and compares
 * every number with freeform::scene::World::contact_summary for the same scene. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "freeform.h"

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s scene.toml [steps]\n", argv[0]);
        return 1;
    }
    int steps = argc > 2 ? atoi(argv[2]) : 10;
    ff_world *w = NULL;
    int rc = ff_world_open(argv[1], 0, &w);
    if (rc != FF_OK) {
        fprintf(stderr, "ff_world_open failed (%d): %s\n", rc, ff_last_error());
        return 1;
    }
    ff_contact_report c;
    memset(&c, 0, sizeof c);
    ff_visible_penetration v;
    memset(&v, 0, sizeof v);
    for (int k = 1; k <= steps; k++) {
        rc = ff_world_step(w);
        if (rc == FF_OK) rc = ff_world_contact_report(w, &c);
        if (rc == FF_OK) rc = ff_world_visible_penetration(w, &v);
        if (rc != FF_OK) {
            fprintf(stderr, "step %d failed (%d): %s\n", k, rc, ff_last_error());
            ff_world_free(w);
            return 1;
        }
        printf("contact %zu enabled %d tested %zu near %zu active %zu penetration %.17g "
               "fraction %.17g islands %zu largest %zu regrouped %zu\n",
               c.step, c.enabled, c.object_pairs_tested, c.object_pairs_near,
               c.sample_pairs_active, c.penetration, c.penetration_fraction, c.islands,
               c.largest_island, c.regrouped);
        printf("visible %zu %.17g %.17g\n", v.step, v.penetration, v.penetration_fraction);
    }
    printf("worst %.17g %.17g over %zu visible %.17g %.17g\n", c.worst_penetration,
           c.worst_penetration_fraction, c.steps_over_tolerance, v.worst_penetration,
           v.worst_penetration_fraction);
    /* Where the worst visible penetration was: which object's surface point, into which. */
    ff_visible_spot spot;
    rc = ff_world_visible_spot(w, &spot);
    if (rc != FF_OK) {
        fprintf(stderr, "ff_world_visible_spot failed (%d): %s\n", rc, ff_last_error());
        ff_world_free(w);
        return 1;
    }
    if (spot.found)
        printf("spot %zu %s %s %.17g %.17g %.17g\n", spot.step,
               ff_world_object_name(w, spot.surface_object),
               ff_world_object_name(w, spot.other_object), spot.rest_point[0],
               spot.rest_point[1], spot.rest_point[2]);
    ff_world_free(w);
    return 0;
}
