/* The records of the colliders' pushes, per vertex (bcState's touch): written by the collider stages
 * (statics.c) and by the loaded walls' (walls.c), turned into the colliders' impulses once a step
 * (walls.c: bc_account_contacts). static_of (2, N): up to two colliders that pushed vertex i, by their
 * place among the scene's [[static]] tables (-1: none); static_push (4, N): their pushes, x and y of the
 * first, then of the second. A third collider shares the second's record. */
#ifndef BC_TOUCH_H
#define BC_TOUCH_H

#include <stdint.h>

/* Add collider k's push (dx, dy) of vertex i (of n) to i's record: its first slot, or its second. */
static inline void bc_account(int64_t i, int64_t k, double dx, double dy, int64_t *static_of, double *static_push,
                              int64_t n) {
    int64_t slot = static_of[i] < 0 || static_of[i] == k ? 0 : 1;
    static_of[slot * n + i] = k;
    static_push[2 * slot * n + i] += dx;
    static_push[(2 * slot + 1) * n + i] += dy;
}

#endif
