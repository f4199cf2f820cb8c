/* statics.h: the static colliders' stage, its entry point (read by cffi) */
#ifndef BC_STATICS_H
#define BC_STATICS_H

#include "blobcore.h"

/* Push the awake vertices out of every collider, fixed or moving: one kernel per solver kind present
 * (plane, segment, circle, polygon: m->statics[k] with shapes), each recording the contacts (s->contact_normal,
 * contact_depth, contact_material) and the pushes (touch: s->static_of, static_push; a loaded wall's also in
 * s->wall_of, wall_push); h the substep (s) */
void bc_collide_statics(const bcContext *ctx, double h);

#endif
