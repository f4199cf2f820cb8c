/* The build's identity and its threads (blobcore.h). */
#include "blobcore.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#ifndef BC_SOURCE_HASH
#define BC_SOURCE_HASH "unknown"
#endif

const char *bc_source_hash(void) { return BC_SOURCE_HASH; }

#ifdef __clang__
const char *bc_compiler(void) { return "clang " __clang_version__; }
#elif defined(__GNUC__)
const char *bc_compiler(void) { return "gcc " __VERSION__; }
#else
const char *bc_compiler(void) { return "unknown"; }
#endif

#ifdef _OPENMP
int bc_has_openmp(void) { return 1; }
void bc_set_threads(int threads) { omp_set_num_threads(threads > 0 ? threads : 1); }
int bc_threads(void) { return omp_get_max_threads(); }
#else
int bc_has_openmp(void) { return 0; }
void bc_set_threads(int threads) { (void)threads; }
int bc_threads(void) { return 1; }
#endif
