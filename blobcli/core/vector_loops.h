/* Loops on vector registers. A loop whose iterations are independent and branch-free runs two doubles at a time
 * on any x86-64 (SSE2), four with AVX2. BC_VECTOR_LOOPS before a function compiles it for both, and the loader
 * picks the one this CPU runs (function multiversioning: GCC, and Clang from 14, on glibc's ifunc), so a library
 * built on one machine runs on any, each at its best. The two give the same bits: a vector lane does the scalar
 * loop's IEEE operations, each rounded on its own (-ffp-contract=off: no fused multiply-add), and sums across
 * iterations are never reordered (no -ffast-math). Elsewhere the function is compiled once, for the target's
 * baseline. The loops must be in the function itself: one inlined into it keeps the baseline's vectors. */
#ifndef BC_VECTOR_LOOPS_H
#define BC_VECTOR_LOOPS_H

#include <stdint.h> /* (on glibc, defines __GLIBC__) */

#if defined(__x86_64__) && defined(__GLIBC__) && defined(__OPTIMIZE__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define BC_VECTOR_LOOPS __attribute__((target_clones("avx2", "default")))
#endif
#endif
#ifndef BC_VECTOR_LOOPS
#define BC_VECTOR_LOOPS
#endif

#endif
