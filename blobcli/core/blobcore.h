/* blobcore: the step of blobsim in C11. The API Python sees (through cffi: blobcli/core/build.py).
 *
 * Every array is a view over a C-contiguous NumPy array that Python owns and fills once per run
 * (blobcli/core/__init__.py): bcModel is read-only during a step, bcState is what the step changes
 * (the state proper and the scratch kept between substeps), bcSettings the numbers of the run.
 * Per-vertex vectors are structure of arrays: an array of shape (R, N) is R rows of N, so row r of
 * vertex i is a[r * N + i] (position: x = position[i], y = position[N + i]). Per-blob tables of
 * shape (B, C) are row-major: blob b's column c is a[b * C + c].
 *
 * This header is read by cffi's parser as it is: declarations only, integer #defines, no
 * preprocessor conditionals but the include guard.
 */
#ifndef BLOBCORE_H
#define BLOBCORE_H

#include <stdint.h>

#define BC_SOLVER_KINDS 4 /* plane, segment, circle, polygon: colliders.SOLVERS */

/* The static colliders of one solver kind (model.StaticSet): shape s owns rows
 * geom[4 * shape_offsets[s] .. 4 * shape_offsets[s + 1]) */
typedef struct bcStaticSet {
    int64_t shapes, rows;
    const double *geom;            /* (rows, 4): the kind's kernel rows as written (colliders.py) */
    const int64_t *shape_offsets;  /* (shapes + 1,) */
    const double *material;        /* (shapes, 4): μ_s, μ_k, e, surface velocity (m/s) */
    const int64_t *index;          /* (shapes,): each one's place among the scene's [[static]] tables */
} bcStaticSet;

/* How each collider moves (model.Walls), by its place among the scene's [[static]] tables */
typedef struct bcWalls {
    int64_t count, keyframes;     /* S colliders, K path keyframes */
    const int64_t *motion;        /* (S,): FIXED 0, VELOCITY 1, PATH 2, LOADED 3 (walls.py) */
    const double *pivot;          /* (S, 2) m */
    const double *drive;          /* (S, 3): VELOCITY vx, vy (m/s), ω (rad/s); LOADED F (N), e_x, e_y */
    const double *mass;           /* (S,) kg */
    const int64_t *path_offsets;  /* (S + 1,) */
    const double *path;           /* (K, 4): t (s), dx, dy (m), turn (rad) */
    const int64_t *kind;          /* (S,): solver kind, index into the kinds */
    const int64_t *shape;         /* (S,): its place in that kind's bcStaticSet */
} bcWalls;

/* model.ModelArrays: computed once per scene (a schedule may swap in its own arrays between calls) */
typedef struct bcModel {
    int64_t blob_count, vertex_count, spring_count;  /* B, N, S (springs) */
    const int64_t *offsets;          /* (B + 1,) */
    const int64_t *blob_of;          /* (N,) */
    const double *inv_mass;          /* (N,) 1/kg */
    const double *rest_length;       /* (N,) m */
    const double *rest_perimeter;    /* (B,) m */
    const double *target_area;       /* (B,) m², signed */
    const double *compliance;        /* (B,) m/N */
    const double *material;          /* (B, 3): μ_s, μ_k, e */
    const double *orient;            /* (B,) ±1 */
    const double *area_compliance;   /* (B,) */
    const double *gas_pressure;      /* (B,) N/m */
    const int64_t *spring_pairs;     /* (S, 2) */
    const double *spring_rest;       /* (S,) m */
    const double *spring_compliance; /* (B,) m/N */
    const double *driving;           /* (B, 3): driving force F_x, F_y (N) at the centre of mass, torque τ (N m,
                                      * counter-clockwise): driving.h; all 0: not driven */
    const double *adhesion;          /* (B,) N/m: what holds a blob, per metre of contact (adhesion.c); 0: not sticky */
    const double *static_adhesion;   /* (S colliders,) N/m: each collider's, by its place among the [[static]] tables */
    bcStaticSet statics[BC_SOLVER_KINDS];
    bcWalls walls;
} bcModel;

/* Where one solver kind's colliders are now (State.placed) */
typedef struct bcPlaced {
    double *geom;   /* (rows, 4) */
    double *aabb;   /* (shapes, 4): xmin, ymin, xmax, ymax */
    double *delta;  /* (shapes, 5): this substep's motion (walls.py) */
} bcPlaced;

/* model.State: what the step changes. Sizes: B blobs, N vertices, P = PAIRS_PER_BLOB B pair slots,
 * S colliders, K = CONTACTS_PER_VERTEX contacts per vertex, V = self_contact.PER_VERTEX pairs a vertex */
typedef struct bcState {
    double *position;            /* (2, N) m */
    double *velocity;            /* (2, N) m/s */
    double *impact;              /* (B, 4) */
    int64_t *pair_key;           /* (P,) */
    double *pair_impact;         /* (P, 4) */
    int64_t *pair_count;         /* (1,) */
    uint8_t *awake;              /* (B,) */
    double *still;               /* (B,) s */
    double *still_center;        /* (B, 2) m */
    double *still_angle;         /* (B,) rad */
    double *previous;            /* (2, N) m */
    double *predicted;           /* (B, 4) */
    double *lam;                 /* (N,) */
    double *contact_normal;      /* (2, N) */
    double *contact_depth;       /* (N,) m */
    double *contact_material;    /* (6, N) */
    double *perimeter_lam;       /* (B,) */
    double *area_lam;            /* (B,) */
    double *spring_lam;          /* (S springs,) */
    double *center;              /* (B, 2) m */
    double *radius;              /* (B,) m */
    double *edges;               /* (5, N) */
    int64_t *c_edge;             /* (K, N) */
    uint8_t *c_hit;              /* (K, N) */
    double *c_normal;            /* (2, K, N) */
    double *anchor;              /* (2, N) m */
    double *budget;              /* (B,) m */
    double *moved;               /* (B,) m */
    double *blob_contact_depth;  /* (N,) m */
    int64_t *stick_edge;         /* (K, N) */
    double *stick_t;             /* (K, N) */
    int64_t *steps_done;         /* (1,) */
    int64_t *substeps_taken;     /* (2,) */
    double *static_pose;         /* (S, 6) */
    double *static_impulse;      /* (S, 3) */
    bcPlaced placed[BC_SOLVER_KINDS];
    int64_t *static_of;          /* touch: (2, N) */
    double *static_push;         /* touch: (4, N) m */
    int64_t *wall_of;            /* touch: (N,) */
    double *wall_push;           /* touch: (2, N) m */
    double *virial;              /* packing: (B, 4), or NULL in an open world */
    int64_t *touching;           /* packing: (P, 2), or NULL */
    double *touching_force;      /* packing: (P, 2) N, each touching pair's contact force on its first blob, or NULL */
    int64_t *touching_count;     /* packing: (1,), or NULL */
    int64_t *self_pairs;         /* self_contact: (2, V N) */
    double *self_values;         /* self_contact: (4, V N) */
    int64_t *self_count;         /* self_contact: (B,) */
    uint8_t *self_near;          /* self_contact: (B,) */
    double *self_chunks;         /* self_contact: (CHUNK_ROWS, N) */
    int64_t *zoned;              /* self_contact: (B,) */
} bcState;

/* pipeline.StepSettings, with the configuration's flags read at run time */
typedef struct bcSettings {
    double dt;              /* s */
    int64_t substeps;       /* the least a step takes ... */
    int64_t most_substeps;  /* ... and the most */
    int64_t iterations;
    double gx, gy;          /* m/s² */
    double damping;         /* 1/s */
    double drag;            /* 1/s */
    double up_x, up_y;      /* -g / |g| */
    double sleep_speed;     /* m/s */
    double time_to_sleep;   /* s (∞: sleeping off) */
    double box_x, box_y;    /* m: the periodic box; 0: an open world */
    double box_tilt;        /* m: γ L_y */
    int64_t method;         /* index into area.METHODS: kot 0, xpbd 1, gas 2, springs 3 */
    int64_t sleep;          /* 0/1: islands at rest go to sleep */
    int64_t moving;         /* 0/1: a collider moves */
    int64_t loaded;         /* 0/1: a collider is a loaded wall */
    int64_t parallel;       /* 0/1: stages split their loops over threads (model.PARALLEL_BLOBS) */
} bcSettings;

/* The scratch one run of the step needs beyond the state: allocated once per call of bc_advance
 * (scratch.c), never seen by Python but through the stage entry points' tests. */
typedef struct bcScratch bcScratch;

/* What a stage reads: the model, the state, the run's settings and scratch. */
typedef struct bcContext {
    const bcModel *m;
    bcState *s;
    const bcSettings *c;
    bcScratch *w;
    int64_t records; /* 0/1: this step keeps the packing records (a periodic box's virial, touching pairs and their
                      * forces: packing_records.h), which only a call's last step needs (bc_advance) */
} bcContext;

bcScratch *bc_scratch_new(const bcModel *m);
void bc_scratch_free(bcScratch *w);

/* The build: a hash of the C sources it was compiled from (blobcli/core/build.py), the compiler that built
 * it, whether it has OpenMP, and the threads its parallel stages run on (1 without OpenMP). */
const char *bc_source_hash(void);
const char *bc_compiler(void);
int bc_has_openmp(void);
void bc_set_threads(int threads);
int bc_threads(void);

#endif
