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

typedef struct fcr_problem {
    int is_global;  /* 1: fclib_global, 0: fclib_local */
    int has_joints; /* a global problem with a G matrix (not read) */
    size_t n;       /* velocities (global), 0 for local */
    size_t nc;      /* contacts */
    tu_csc M, H;    /* global: n x n, n x 3nc */
    tu_csc W;       /* local: 3nc x 3nc */
    double *f, *w;  /* global: n, 3nc */
    double *q;      /* local: 3nc */
    double *mu;     /* nc */
    int encoding[2]; /* nz code seen for (M, H) or (W, -) as in the file: -1, -2 or >= 0 */
} fcr_problem;

/* Reads `path`. Returns 0 on success; otherwise writes a message into err (errlen bytes)
 * and returns -1 (the problem is then empty and needs no fcr_free). */
int fcr_read(const char *path, fcr_problem *out, char *err, size_t errlen);

void fcr_free(fcr_problem *p);

#ifdef __cplusplus
}
#endif

#endif
