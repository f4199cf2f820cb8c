/* perimeter.h: the perimeter stage's entry point (read by cffi) */
#ifndef BC_PERIMETER_H
#define BC_PERIMETER_H

#include "blobcore.h"

void bc_solve_perimeter(const bcContext *ctx, double h);

#endif
