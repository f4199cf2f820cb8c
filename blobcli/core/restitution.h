/* restitution.h: the bounce stages' entry points: off statics, between blobs (read by cffi) */
#ifndef BC_RESTITUTION_H
#define BC_RESTITUTION_H

#include "blobcore.h"

double bc_rest_speed(double g, double h);
void bc_restitution(const bcContext *ctx, double rest_speed);
void bc_blob_restitution(const bcContext *ctx, double rest_speed);

#endif
