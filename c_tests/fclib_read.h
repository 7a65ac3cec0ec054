/* A small FCLib reader written with the HDF5 C API, independent of the cadmm library, for
 * the reference tests. Reads /fclib_global (M, H, f, w, mu; joints are reported, not read)
 * and /fclib_local (W, q, mu). Matrices are returned in normalized CSC (rows sorted within
 * each column, duplicates summed) whatever their encoding in the file (docs/algorithms.md
 * §10): nz = -1 compressed column, nz = -2 compressed row, nz >= 0 triplets with
 * i = row index and p = column index (as Siconos writes them). */
#ifndef CADMM_FCLIB_READ_H
#define CADMM_FCLIB_READ_H

#include "test_util.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The reader fills a tu_problem (test_util.h): is_global, has_joints (a global problem
 * with a G matrix, which is not read), n, nc, M, H, f, w (global) or W, q (local), mu, and
 * encoding (the nz code seen for (M, H) or (W, -) in the file: -1, -2 or >= 0). */
typedef tu_problem fcr_problem;

/* Reads `path`. Returns 0 on success; otherwise writes a message into err (errlen bytes)
 * and returns -1 (the problem is then empty and needs no fcr_free). */
int fcr_read(const char *path, fcr_problem *out, char *err, size_t errlen);

void fcr_free(fcr_problem *p);

#ifdef __cplusplus
}
#endif

#endif
