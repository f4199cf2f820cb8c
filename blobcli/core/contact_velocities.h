/* contact_velocities.h: the blob contacts' velocity stage (read by cffi) */
#ifndef BC_CONTACT_VELOCITIES_H
#define BC_CONTACT_VELOCITIES_H

#include "blobcore.h"

/* At every contact that pushed this substep (c_hit): no approach along its last push's normal, and Coulomb
 * friction on the tangential relative velocity; the impulses go into the virial in a periodic box. */
void bc_blob_contact_velocities(const bcContext *ctx, double h);

#endif
