/* The periodic box (Lees–Edwards): the one home of "the vector from blob a to blob b". */
#ifndef BC_PERIODIC_H
#define BC_PERIODIC_H

#include <math.h>
#include <stdint.h>

/* The box: L_x, L_y and the shift γ L_y of the row of images above; L_x = 0: an open world */
typedef struct bcBox {
    double lx, ly, tilt;
} bcBox;

/* (s_x, s_y), the shift that carries blob a to the image of it nearest blob b (centres (B, 2)), so that
 * a vertex p of a meets b's vertices as p + s. The images lie at n_x e_1 + n_y e_2, e_1 = (L_x, 0),
 * e_2 = (γ L_y, L_y): n_y = round(d_y / L_y), n_x = round((d_x - n_y γ L_y) / L_x), d = c_b - c_a.
 * In an open world (0, 0) without arithmetic, so it keeps its bits; and, without the divisions, for d
 * within a quarter box of 0, where both roundings give n = 0. */
static inline void bc_image(const double *center, int64_t a, int64_t b, bcBox box, double *sx, double *sy) {
    *sx = 0.0;
    *sy = 0.0;
    if (box.lx == 0.0) return;
    double dx = center[2 * b] - center[2 * a], dy = center[2 * b + 1] - center[2 * a + 1];
    if (fabs(dy) < 0.25 * box.ly && fabs(dx) < 0.25 * box.lx) return;
    double ny = floor(dy / box.ly + 0.5);
    double nx = floor((dx - ny * box.tilt) / box.lx + 0.5);
    *sx = nx * box.lx + ny * box.tilt;
    *sy = ny * box.ly;
}

static inline bcBox bc_box(double lx, double ly, double tilt) {
    bcBox box = {lx, ly, tilt};
    return box;
}

#endif
