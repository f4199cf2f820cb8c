/* sleep.h: the sleeping islands' entry points (read by cffi) */
#ifndef BC_SLEEP_H
#define BC_SLEEP_H

#include "blobcore.h"

int64_t bc_update_sleep(const bcContext *ctx);
int64_t bc_awake_count(const bcContext *ctx);
void bc_begin_still(const bcContext *ctx);

#endif
