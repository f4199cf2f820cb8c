/* measure.h: per-blob measurements taken at recorded frames, and the runaway check (read by cffi) */
#ifndef BC_MEASURE_H
#define BC_MEASURE_H

#include "blobcore.h"

#define BC_SELF_CROSSING_MAX_VERTICES 4096 /* larger rings are not checked for self-crossing (O(n²) per ring) */

/* Index of the first vertex of s->position that is non-finite or beyond `limit` (m), or -1 */
int64_t bc_first_runaway(const bcContext *ctx, double limit);

/* The same over positions (2, n) */
int64_t bc_first_runaway_in(const double *position, int64_t n, double limit);

/* Index of the first collider whose pose row (pose: (walls, BC_WALL_POSE_COLUMNS)) holds a non-finite value or a
 * displacement beyond `limit` (m), or -1 */
int64_t bc_first_runaway_wall(const double *pose, int64_t walls, double limit);

/* Each blob's signed area (m²) and kinetic energy (J) into area (blob_count,) and kinetic (blob_count,), from
 * positions and velocities (2, n), inverse masses (n,) and offsets (blob_count + 1,) */
void bc_blob_measures(const double *position, const double *velocity, int64_t n, const double *inv_mass,
                      const int64_t *offsets, int64_t blob_count, double *area, double *kinetic);

/* faults[b] = 1 if blob b's signed area has lost its rest sign orient[b] (inside out), 2 if its ring crosses
 * itself (two non-adjacent edges properly cross), else 0; positions (2, n) */
void bc_shape_faults(const double *position, int64_t n, const int64_t *offsets, int64_t blob_count,
                     const double *orient, int64_t *faults);

#endif
