/* walls.h: the entry points of the walls that move and of the colliders' records (read by cffi) */
#ifndef BC_WALLS_H
#define BC_WALLS_H

#include "blobcore.h"

/* How a collider moves (bcWalls.motion) */
#define BC_FIXED 0
#define BC_VELOCITY 1
#define BC_PATH 2
#define BC_LOADED 3
#define BC_WALL_POSE_COLUMNS 6 /* s->static_pose: dx, dy (m), θ (rad), s (m), V (m/s), s at the substep's start (m) */

/* Whether any collider moves (a path, a velocity or a load) */
int bc_any_moves(const bcContext *ctx);

/* Move every collider that moves from its pose at t to its pose at t + h (s): its rows and bounding box in
 * s->placed, its motion over the substep in delta, its pose in s->static_pose; wake the sleeping blobs whose
 * bounding box meets a moving collider's */
void bc_place_walls(const bcContext *ctx, double t, double h);

/* A state just built: every collider that moves at its pose at t = 0 (a path may start displaced) */
void bc_place_initial(const bcContext *ctx);

/* Share this iteration's pushes of each loaded wall between it and the vertices it pushed; then clear the
 * iteration's records (s->wall_of, wall_push) */
void bc_yield_loaded_walls(const bcContext *ctx);

/* After a substep of h (s): each loaded wall's velocity from its motion */
void bc_finish_loaded_walls(const bcContext *ctx, double h);

/* Record the velocity-level impulses of the substep's static contacts as the colliders' pushes (but a loaded
 * wall's: bc_react_loaded_walls) */
void bc_record_contact_impulses(const bcContext *ctx, double h);

/* The velocity-level impulses of the substep's static contacts act on a loaded wall too, shared as its pushes */
void bc_react_loaded_walls(const bcContext *ctx, double h);

/* Each loaded polygon's corner (a loaded segment's end) inside a ring pushes the ring's edge nearest it off it, as the
 * kernels push vertices (recorded for the wall's share and force) */
void bc_collide_loaded_corners(const bcContext *ctx, double h);

/* Note the positions before bc_stop_impacts ... */
void bc_keep_impact_positions(const bcContext *ctx);

/* ... and record what it moved of a blob whose deepest push was a loaded wall's as that wall's pushes */
void bc_share_impact_stops(const bcContext *ctx);

/* The substeps the loaded walls' loads need at the step's start: at least the scene's, at most its most */
int64_t bc_loaded_substeps(const bcContext *ctx);

/* At a step's start: which side of each loaded wall each awake blob beside it is wholly on (scratch wall_side) ... */
void bc_note_wall_sides(const bcContext *ctx);

/* ... and at its end, b × S + k for the first blob b wholly on the other side of loaded wall k now, or with one of
 * its corners deep inside, or -1 */
int64_t bc_find_passed_blob(const bcContext *ctx);

/* b × S + k: the first awake blob b beside a moving collider k that is inside out, or crushed (its area off by
 * more than 10%), or -1 */
int64_t bc_first_broken_blob(const bcContext *ctx);

/* The step's pushes as impulses and moments on each collider (s->static_impulse); clear the vertices' records */
void bc_account_contacts(const bcContext *ctx, double h);

#endif
