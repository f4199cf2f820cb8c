/* integrate.h: the time integration stages' entry points (read by cffi): damping, drag, substeps, prediction,
 * impacts, the velocity update */
#ifndef BC_INTEGRATE_H
#define BC_INTEGRATE_H

#include "blobcore.h"

void bc_damp_deformation(const bcContext *ctx, double factor);
void bc_drag_motion(const bcContext *ctx, double factor);
int64_t bc_substeps_for(const bcContext *ctx, double g);
/* How many blobs the most heavily loaded blob carries, itself included, from positions alone (along up) */
int64_t bc_rows_stacked(const bcContext *ctx);
void bc_predict(const bcContext *ctx, double h);
void bc_stop_impacts(const bcContext *ctx);
void bc_stop_impact_velocities(const bcContext *ctx);
void bc_update_velocities(const bcContext *ctx, double h);

#endif
