/* collide_limits.h: the blob contacts' fixed sizes, as sim/collide.py sets them (read by cffi) */
#ifndef BC_COLLIDE_LIMITS_H
#define BC_COLLIDE_LIMITS_H

#define BC_PAIRS_PER_BLOB 64     /* past this many pairs per blob (blobs spawned on top of each other) the step stops */
#define BC_CONTACTS_PER_VERTEX 2 /* a vertex keeps contacts with its two nearest neighbouring blobs */
#define BC_MAX_STRIPS 8          /* the resolution cuts a scene into at most this many vertical strips */
#define BC_BLOBS_PER_STRIP 32    /* ... B // 32 of them, at least 1 */
#define BC_FOUND_PER_BLOB 8      /* the broad phase keeps this many of each blob's pairs as it counts them */

#endif
