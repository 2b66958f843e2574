/*
 * freeform C API: skinning eigenmodes from RKPM kernels (mesh-free reduced-order elasticity),
 * and the live simulation of a scene file (open, step, read positions, move targets, free).
 *
 * Library: libfreeform_capi.so / libfreeform_capi.a, built by
 *     cargo build --release -p freeform-capi
 * Link:    cc app.c -Iffi/include -Ltarget/release -lfreeform_capi -lm
 * Guide:   docs/c-api.md.
 * Examples: examples/basis.c (a basis from arrays: eigenvalues, weights, gradients);
 *           examples/step.c (steps examples/step.toml, moving a held end and a floor);
 *           examples/gradient.c (a recorded run of two blocks in contact, its gradients).
 *
 * Conventions
 *   - Every function returning int returns FF_OK (0) or an FF_ERR_* code; then
 *     ff_last_error() gives the message (per thread, valid until the next failure there).
 *   - Arrays are row-major doubles; lengths are element counts (size_t). Output arrays come
 *     with their capacity; a too small one gives FF_ERR_BUFFER_TOO_SMALL.
 *   - Units: positions in metres, volumes in m^3, Young's modulus in Pa, density in kg/m^3;
 *     eigenvalues in Pa/m^2; time in seconds; gravity in m/s^2.
 *   - Indices are 0-based; an index out of range gives FF_ERR_INVALID_ARGUMENT with a message
 *     naming the index and the count.
 *   - Functions are thread-safe on distinct bases and worlds; a basis may be read from several
 *     threads. A world may be read (const ff_world *) from several threads at once, but
 *     stepping or changing it (ff_world *) needs it to yourself.
 *   - The library computes with all cores (rayon); set RAYON_NUM_THREADS to limit them
 *     (results are bit-identical for the same thread count).
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
    FF_ERR_PANIC = 6,             /* internal error (caught); please report it */
    FF_ERR_IO = 7,                /* a file could not be read (scene file, shape file) */
    FF_ERR_STRICT = 8             /* strict mode: a warning (non-converged step, inversion,
                                     Newton Hessian fallback, poor basis) stopped the world */
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

/* ---------------------------------------------------------------------------------------- */
/* Live simulation: a scene file (TOML, docs/scenes.md) stepped from C.                      */
/* Objects, boundaries and colliders are indexed from 0 in the order of the scene file's      */
/* [[object]], [[object.boundary]] and [[collider]] tables.                                   */

/* An opaque scene being simulated. */
typedef struct ff_world ff_world;

/* The last step of one object (see ff_world_step_report). */
typedef struct ff_step_report {
    size_t step;                 /* step number, 1-based */
    size_t iterations;           /* solver iterations */
    size_t evaluations;          /* energy/gradient evaluations */
    int converged;               /* 1 if the solver tolerance was met, 0 if not */
    int line_search_failed;      /* 1 if the line search could not decrease the energy */
    double residual;             /* final convergence measure (compare with solver.tol) */
    double energy;               /* incremental potential at the end of the step, J */
    double wall_ms;              /* wall time of the step, ms */
    double min_det;              /* smallest det F over the cubature points */
    size_t inverted;             /* cubature points with det F <= 0 */
    size_t contacts;             /* cubature points penetrating a collider */
    size_t line_search_cutbacks; /* line-search step halvings, summed over iterations */
} ff_step_report;

/* Object-object contact ([contact] scenes) of the last world step and the worst of the run
 * (see ff_world_contact_report). A struct of its own: ff_step_report keeps its layout. */
typedef struct ff_contact_report {
    int enabled;                       /* 1 if the scene has a [contact] section, else 0 */
    size_t step;                       /* step of the row, 1-based; 0 before the first step */
    size_t object_pairs_tested;        /* object pairs whose grown boxes were compared */
    size_t object_pairs_near;          /* object pairs whose boxes met (solved together) */
    size_t sample_pairs_active;        /* sample pairs within contact distance at step end */
    double penetration;                /* deepest object-object penetration, metres */
    double penetration_fraction;       /* the same / smaller rest diagonal of the two objects */
    size_t islands;                    /* islands of two or more objects */
    size_t largest_island;             /* objects in the largest island (0: none) */
    size_t regrouped;                  /* objects solved again (ended touching another island) */
    double wall_ms;                    /* wall time of the whole world step, ms */
    double worst_penetration;          /* worst penetration of the run so far, metres */
    double worst_penetration_fraction; /* the same / smaller diagonal of its two objects */
    size_t steps_over_tolerance;       /* steps deeper than contact.penetration_tolerance */
} ff_contact_report;

/* The visible penetration ([contact] scenes) of the last world step and the worst of the run
 * (see ff_world_visible_penetration): each object's own surface points (box faces with their
 * edges and corners, sphere lattice, mesh vertices, the derived surface of a cloud, splat or
 * image) behind another object's contact samples. ff_contact_report's penetration is the
 * samples' own figure. A struct of its own: ff_contact_report keeps its layout. */
typedef struct ff_visible_penetration {
    int enabled;                       /* 1 if the scene has a [contact] section, else 0 */
    size_t step;                       /* step of the figures, 1-based; 0 before the first */
    double penetration;                /* deepest surface point at the step's end, metres */
    double penetration_fraction;       /* the same / smaller rest diagonal of the two objects */
    double worst_penetration;          /* the deepest of the run so far, metres */
    double worst_penetration_fraction; /* the same / smaller diagonal of its two objects */
} ff_visible_penetration;

/* Where the run's worst visible penetration was (see ff_world_visible_spot). */
typedef struct ff_visible_spot {
    int found;             /* 1 once a surface point has reached into another object, else 0 */
    size_t step;           /* the step it was measured after, 1-based */
    size_t surface_object; /* index of the object whose surface point it is */
    size_t other_object;   /* index of the object whose contact samples it reached into */
    double rest_point[3];  /* the point in its object's rest frame (before placement), metres */
} ff_visible_spot;

/* Open the scene file scene_path and set up every object (basis from the scene's cache or
 * computed, reduced model, render points), as `freeform run` does: relative paths in the
 * scene resolve against the scene file's directory; no frames are written, nothing is
 * printed. strict != 0 turns warnings (setup and every step) into FF_ERR_STRICT. On success
 * *out owns the world (release it with ff_world_free); on failure *out is NULL: FF_ERR_IO for
 * an unreadable scene or shape file, FF_ERR_INVALID_ARGUMENT for a malformed scene (the
 * message gives the line), FF_ERR_COVERAGE or FF_ERR_EIGENSOLVER for a basis that cannot be
 * built (the message names the object). */
int ff_world_open(const char *scene_path, int strict, ff_world **out);

/* Release a world (NULL is ignored); strings it handed out die with it. */
void ff_world_free(ff_world *world);

/* Advance every object by one time step (backward Euler, the scene's dt). A step that does
 * not converge is not an error: ff_world_step_report says so and a warning is added. In
 * strict mode the first warning gives FF_ERR_STRICT and the world stops for good (later steps
 * give FF_ERR_STRICT; reading stays possible); likewise after FF_ERR_PANIC in a step. */
int ff_world_step(ff_world *world);

/* The last step of object `object` into *out (FF_ERR_INVALID_ARGUMENT before the first). */
int ff_world_step_report(const ff_world *world, size_t object, ff_step_report *out);

/* Object-object contact of the last world step and the worst of the run into *out. A scene
 * without [contact] gives all zeros (enabled 0); before the first step, step is 0. */
int ff_world_contact_report(const ff_world *world, ff_contact_report *out);

/* The visible penetration of the last world step and the worst of the run into *out. A scene
 * without [contact] gives all zeros (enabled 0); before the first step, step is 0. */
int ff_world_visible_penetration(const ff_world *world, ff_visible_penetration *out);

/* Where the run's worst visible penetration was into *out: found 0 without [contact], before
 * the first step, or while no surface point has reached in (all fields 0 then). */
int ff_world_visible_spot(const ff_world *world, ff_visible_spot *out);

/* Steps of object `object` that did not converge so far (0 for NULL or a bad index). */
size_t ff_world_nonconverged_steps(const ff_world *world, size_t object);

/* Simulated time and time step, s; steps taken. 0 for NULL. */
double ff_world_time(const ff_world *world);
double ff_world_dt(const ff_world *world);
size_t ff_world_steps(const ff_world *world);

/* Counts: objects, colliders of the scene, boundaries of object `object`. 0 for NULL or a bad
 * index. */
size_t ff_world_object_count(const ff_world *world);
size_t ff_world_collider_count(const ff_world *world);
size_t ff_world_boundary_count(const ff_world *world, size_t object);

/* The index of the object named `name` into *out (FF_ERR_INVALID_ARGUMENT, listing the names,
 * if there is none). */
int ff_world_object_index(const ff_world *world, const char *name, size_t *out);

/* The name of object `object` (NULL for NULL or a bad index); valid until ff_world_free. */
const char *ff_world_object_name(const ff_world *world, size_t object);

/* Number N of render points of object `object` (0 for NULL or a bad index): a mesh's
 * vertices, a point cloud's points, or a primitive's (box:, sphere:) integration points. */
size_t ff_world_point_count(const ff_world *world, size_t object);

/* Deformed render points, N x 3 row-major (out[3 i + d], metres; what `freeform run` writes as
 * frames), into out[len >= 3 N]. */
int ff_world_positions(const ff_world *world, size_t object, double *out, size_t len);

/* Rest positions of the render points (before the placement), N x 3, into out[len >= 3 N]. */
int ff_world_rest_positions(const ff_world *world, size_t object, double *out, size_t len);

/* Hold boundary `boundary` of object `object` at the rigid pose x = R X + t of its placed rest
 * positions X, from the next step on (whatever the time: a target moved between steps).
 * rotation: R, 9 doubles row-major, a proper rotation (orthonormal, det +1, to 1e-9; else
 * FF_ERR_INVALID_ARGUMENT), NULL for the identity; translation: t, 3 doubles, metres. */
int ff_world_set_boundary_pose(ff_world *world, size_t object, size_t boundary,
                               const double *rotation, const double *translation);

/* Move collider `collider` to the pose x -> R x + t of its definition in the scene, for every
 * object from the next step on (absolute, not accumulated: a kinematic obstacle; it replaces the
 * collider's scripted motion, and for a collider with a parent it is relative to the parent's
 * frame). Any shape takes any rigid pose. rotation and translation as above. */
int ff_world_set_collider_pose(ff_world *world, size_t collider, const double *rotation,
                               const double *translation);

/* Gravity for every object from the next step on: gravity[3], m/s^2; NULL turns it off. */
int ff_world_set_gravity(ff_world *world, const double *gravity);

/* Length of object `object`'s state vectors z and zdot: 12 (m + 1) for m + 1 modes (0 for NULL
 * or a bad index). z holds the 3 x 4 affine handles Z_j of x(X) = X + sum_j W_j(X) Z_j [X; 1]:
 * z[4 (m + 1) r + 4 j + a] = Z_j[r][a] (row r < 3, column a < 4); zdot = dz/dt (per s). */
size_t ff_world_state_len(const ff_world *world, size_t object);

/* Copy the state into z[len] and zdot[len] (len >= ff_world_state_len). */
int ff_world_get_state(const ff_world *world, size_t object, double *z, double *zdot,
                       size_t len);

/* Set the state from z[len] and zdot[len] (len == ff_world_state_len, finite values), e.g. one
 * saved with ff_world_get_state; the solver's history is dropped, time goes on. All or
 * nothing: a refused state leaves the object as it was. */
int ff_world_set_state(ff_world *world, size_t object, const double *z, const double *zdot,
                       size_t len);

/* Warnings so far (setup, steps that did not converge, inversions, Hessian fallbacks): their
 * number, and warning i (NULL for NULL or a bad index; valid until ff_world_free). */
size_t ff_world_warning_count(const ff_world *world);
const char *ff_world_warning(const ff_world *world, size_t index);

/* ---- Gradients through a recorded run (docs/gradients.md; docs/c-api.md "Gradients") ---- */

typedef struct ff_recording ff_recording;
typedef struct ff_gradients ff_gradients;

/* Record every object of world from its current state for about steps steps into *out (the
 * tapes' memory is checked first); step it with ff_recording_step; free with
 * ff_recording_free. Objects in contact ([contact] scenes) are recorded with their islands. */
int ff_recording_start(const ff_world *world, size_t steps, ff_recording **out);
void ff_recording_free(ff_recording *rec);
/* Steps recorded (0 for NULL or a recording the reverse pass consumed). */
size_t ff_recording_steps(const ff_recording *rec);
/* One ff_world_step, recorded; refused (nothing moves) when an object was changed since. */
int ff_recording_step(ff_recording *rec, ff_world *world);

/* The reverse pass of a loss L(z_0, ..., z_T) into *out (free with ff_gradients_free):
 * dl_dz[objects] (the world's object count), each NULL (L does not see the object) or dL/dz
 * per frame, (T + 1) x ff_world_state_len doubles row-major, row 0 the start. Consumes the
 * recording once it succeeds (a refused loss leaves it). */
int ff_recording_backward(ff_recording *rec, const ff_world *world, const double *const *dl_dz,
                          size_t objects, ff_gradients **out);
void ff_gradients_free(ff_gradients *g);

/* Object object's dL/dE (per Pa) and dL/dnu, summed over it, into out[2]. */
int ff_gradients_material(const ff_gradients *g, size_t object, double *out);
/* Object object's dL/dg (per m/s^2) into out[3]; FF_ERR_INVALID_ARGUMENT without gravity. */
int ff_gradients_gravity(const ff_gradients *g, size_t object, double *out);
/* Object object's dL/dz_0 and dL/dzdot_0 into z0[len] and zdot0[len]
 * (len >= ff_world_state_len). */
int ff_gradients_state(const ff_gradients *g, size_t object, double *z0, double *zdot0,
                       size_t len);
/* Object object's dL/dmu (0 without collider friction) and dL/dkappa (per Pa/m^2) of collider
 * collider into out[2]. */
int ff_gradients_collider(const ff_gradients *g, size_t object, size_t collider, double *out);
/* dL/dkappa (per Pa/m^2, of the stiffness the scene gives) and dL/dmu of the pair of objects
 * (a, b) into out[2] (a == b: self-contact); FF_ERR_INVALID_ARGUMENT without [contact]. */
int ff_gradients_contact_pair(const ff_gradients *g, size_t a, size_t b, double *out);

/* Positions of count rest points (count x 3, metres) of object object under its current
 * state into out[len] (len >= 3 count). */
int ff_world_map_points(const ff_world *world, size_t object, const double *points,
                        size_t count, double *out, size_t len);
/* dL/dz of a loss on those positions from dl_dx (count x 3) into out[len]
 * (len >= ff_world_state_len): the transpose of ff_world_map_points's map. */
int ff_world_positions_adjoint(const ff_world *world, size_t object, const double *points,
                               size_t count, const double *dl_dx, double *out, size_t len);

/* ---- The eigensolver over your own operators (docs/c-api.md "Operators") ---- */

/* y = A x for a block of ncols vectors of length k, column-major (column j at x + j k). Return
 * 0 on success; anything else stops the solve (call ff_callback_error first to give the
 * message). y arrives filled with NaN: a callback that writes too little is caught. */
typedef int (*ff_apply_fn)(void *ctx, const double *x, double *y, size_t k, size_t ncols);

/* The message of the failure a callback is about to report (call from inside it). */
void ff_callback_error(const char *message);

/* The nev smallest pairs of H x = lambda M x (K x K symmetric; H PSD with the constant vector
 * in its null space, M SPD) by the native LOBPCG, H and M applied only through h and m (with
 * contexts h_ctx, m_ctx). pre (may be NULL; context pre_ctx): T ~ (H + sigma M)^-1 on residual
 * blocks; if NULL, Jacobi when both h_diag and m_diag (k doubles each, may be NULL) are given,
 * else none. Writes values[nev] (ascending, first 0) and vectors[k nev] (row-major, M-
 * orthonormal); *iterations (may be NULL) gets LOBPCG's count. Callbacks run on the calling
 * thread, one at a time. FF_ERR_EIGENSOLVER carries a failing callback's message. */
int ff_eigen_solve_operators(size_t k, size_t nev, double tol, size_t max_iter, ff_apply_fn h,
                             void *h_ctx, ff_apply_fn m, void *m_ctx, ff_apply_fn pre,
                             void *pre_ctx, const double *h_diag, const double *m_diag,
                             double *values, double *vectors, size_t *iterations);

#ifdef __cplusplus
}
#endif

#endif /* FREEFORM_H */
