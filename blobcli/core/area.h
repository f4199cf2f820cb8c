/* area.h: the area stages' entry points (read by cffi): one per area method (kot, xpbd, gas, springs), and the
 * exact area projection of one ring, which self_contact.c also calls */
#ifndef BC_AREA_H
#define BC_AREA_H

#include "blobcore.h"

void bc_project_area(double *position, int64_t n, const double *inv_mass, int64_t o, int64_t e, double target);
void bc_area_kot(const bcContext *ctx);
void bc_area_xpbd(const bcContext *ctx, double h);
void bc_area_gas(const bcContext *ctx, double scale);
void bc_area_springs(const bcContext *ctx, double h);

#endif
