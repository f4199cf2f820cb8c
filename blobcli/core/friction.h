/* Friction, restitution and adhesion at a contact: how two materials combine, written once for every contact stage.
 * Materials combine as Box2D does: μ = √(μ_a μ_b) (static and kinetic alike), e = max(e_a, e_b); adhesion as
 * restitution does, a = max(a_a, a_b) (bc_mix_adhesion). */
#ifndef BC_FRICTION_H
#define BC_FRICTION_H

#include <math.h>

#include "ring.h"

/* μ of a contact between materials of coefficients μ_a and μ_b: √(μ_a μ_b) */
static inline double bc_mix_friction(double mu_a, double mu_b) { return sqrt(mu_a * mu_b); }

/* e of a contact: the bouncier material's, max(e_a, e_b) (Python's max: e_a unless e_b is strictly greater) */
static inline double bc_mix_restitution(double e_a, double e_b) { return bc_max(e_a, e_b); }

/* a of a contact (N/m): the stickier side's, max(a_a, a_b). Glue on either side holds: a sticky blob sticks to a
 * clean wall (Gish on any wall) and a sticky wall holds a clean blob, which the smaller of the two or √(a_a a_b)
 * would not (0 when either side is clean); and two glued sides hold as one layer of glue does, not as two (a sum
 * would make a sticky blob on a sticky floor hold twice what either holds alone). Blob on blob, the same rule. */
static inline double bc_mix_adhesion(double a_a, double a_b) { return bc_max(a_a, a_b); }

/* Coulomb's rule on a slip (|f_t| <= μ |f_n|, at position or velocity level): the share of the slip it removes,
 * all of it within the static limit μ_s D, else the kinetic limit μ_k D's worth (at most all) */
static inline double bc_coulomb_cut(double slip, double static_limit, double kinetic_limit) {
    return slip <= static_limit ? 1.0 : bc_min(kinetic_limit / slip, 1.0);
}

#endif
