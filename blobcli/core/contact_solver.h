/* contact_solver.h: the blob contacts' solver, at position level (read by cffi) */
#ifndef BC_CONTACT_SOLVER_H
#define BC_CONTACT_SOLVER_H

#include "blobcore.h"

/* One iteration's pass over the kept blob contacts (s->c_edge): every vertex inside the other blob is pushed
 * out, with friction, blob by blob by the strips of the scratch (each blob's contacts together); `reverse`
 * (odd iterations): each strip's blobs in reverse order. Writes c_edge, c_hit, c_normal, blob_contact_depth,
 * stick_edge, stick_t, the positions and, in a periodic box, the virial. */
void bc_resolve_blob_contacts(const bcContext *ctx, int reverse, double h);

/* The push of vertex (px, py) kept on edge e0 → e1 of ring o..e (winding orient) near a convex corner, where it
 * is behind both edges' lines: e0, e1, t, the normal (nx, ny) and C turned toward the corner's bisector. */
void bc_near_convex_corner(const double *pos, int64_t n, double orient, int64_t o, int64_t e, int64_t *e0,
                           int64_t *e1, double *t, double *nx, double *ny, double *C, double px, double py);

#endif
