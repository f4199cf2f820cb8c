/* narrow_phase.h: the narrow phase's entry point, the blob contacts found and kept (read by cffi) */
#ifndef BC_NARROW_PHASE_H
#define BC_NARROW_PHASE_H

#include "blobcore.h"

/* Every iteration, after the area stage: split deeply overlapping pairs, then find the contacts (c_edge) of every
 * awake blob (first: at the start of the step), or only of those that outgrew their budget or were split, and of
 * their partners. reach_time: the time left in the step, (substeps - sub) h; g = |g|. Reads the broad phase's
 * pairs and partners in the scratch. */
void bc_keep_blob_contacts(const bcContext *ctx, int first, double reach_time, double g);

#endif
