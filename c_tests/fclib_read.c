/* Independent FCLib reader (see fclib_read.h). Uses only the HDF5 C API. */
#include "fclib_read.h"

#include <hdf5.h>
#include <stdarg.h>

static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    va_list ap;
    if (err == NULL || errlen == 0) return;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

/* Number of elements of a dataset, or -1. */
static long long dataset_len(hid_t parent, const char *name)
{
    hid_t d, s;
    hssize_t n;
    if (H5Lexists(parent, name, H5P_DEFAULT) <= 0) return -1;
    d = H5Dopen2(parent, name, H5P_DEFAULT);
    if (d < 0) return -1;
    s = H5Dget_space(d);
    n = s < 0 ? -1 : H5Sget_simple_extent_npoints(s);
    if (s >= 0) H5Sclose(s);
    H5Dclose(d);
    return (long long)n;
}

/* Reads a whole dataset converted to `memtype` into a new array of *len elements. */
static void *read_dataset(hid_t parent, const char *name, hid_t memtype, size_t elem,
                          size_t *len, char *err, size_t errlen)
{
    long long n = dataset_len(parent, name);
    hid_t d;
    void *buf;
    if (n < 0) {
        set_err(err, errlen, "dataset '%s' missing or unreadable", name);
        return NULL;
    }
    buf = tu_calloc((size_t)n, elem);
    d = H5Dopen2(parent, name, H5P_DEFAULT);
    if (d < 0 || (n > 0 && H5Dread(d, memtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) < 0)) {
        if (d >= 0) H5Dclose(d);
        free(buf);
        set_err(err, errlen, "cannot read dataset '%s'", name);
        return NULL;
    }
    H5Dclose(d);
    *len = (size_t)n;
    return buf;
}

static int read_scalar(hid_t parent, const char *name, long long *value, char *err,
                       size_t errlen)
{
    size_t len = 0;
    int64_t *v = (int64_t *)read_dataset(parent, name, H5T_NATIVE_INT64, sizeof(int64_t),
                                         &len, err, errlen);
    if (v == NULL) return -1;
    if (len < 1) {
        free(v);
        set_err(err, errlen, "dataset '%s' is empty", name);
        return -1;
    }
    *value = (long long)v[0];
    free(v);
    return 0;
}

typedef struct triplet {
    int64_t row, col;
    double value;
} triplet;

static int cmp_triplet(const void *a, const void *b)
{
    const triplet *x = (const triplet *)a, *y = (const triplet *)b;
    if (x->col != y->col) return x->col < y->col ? -1 : 1;
    if (x->row != y->row) return x->row < y->row ? -1 : 1;
    return 0;
}

/* Sorts the triplets (column-major), sums duplicates and fills a CSC matrix. */
static void triplets_to_csc(triplet *t, size_t nt, size_t nrows, size_t ncols, tu_csc *a)
{
    size_t k = 0;
    qsort(t, nt, sizeof(triplet), cmp_triplet);
    a->nrows = nrows;
    a->ncols = ncols;
    a->colptr = (int64_t *)tu_calloc(ncols + 1, sizeof(int64_t));
    a->rowind = (int64_t *)tu_calloc(nt, sizeof(int64_t));
    a->values = (double *)tu_calloc(nt, sizeof(double));
    for (size_t e = 0; e < nt; ++e) {
        if (k > 0 && a->rowind[k - 1] == t[e].row && e > 0 && t[e - 1].col == t[e].col) {
            a->values[k - 1] += t[e].value; /* duplicate: summed */
            continue;
        }
        a->rowind[k] = t[e].row;
        a->values[k] = t[e].value;
        a->colptr[t[e].col + 1]++;
        ++k;
    }
    for (size_t j = 0; j < ncols; ++j) a->colptr[j + 1] += a->colptr[j];
}

/* Reads the matrix group parent/name into normalized CSC. *encoding gets -1 (CSC), -2 (CSR)
 * or 0 (triplets). */
static int read_matrix(hid_t parent, const char *name, tu_csc *a, int *encoding, char *err,
                       size_t errlen)
{
    hid_t g;
    long long m = 0, n = 0, nz = 0;
    size_t lp = 0, li = 0, lx = 0, nt = 0;
    int64_t *p = NULL, *idx = NULL;
    double *x = NULL;
    triplet *t = NULL;
    int rc = -1;
    char sub[256];

    memset(a, 0, sizeof(*a));
    if (H5Lexists(parent, name, H5P_DEFAULT) <= 0) {
        set_err(err, errlen, "matrix '%s' missing", name);
        return -1;
    }
    g = H5Gopen2(parent, name, H5P_DEFAULT);
    if (g < 0) {
        set_err(err, errlen, "cannot open matrix group '%s'", name);
        return -1;
    }
    if (read_scalar(g, "m", &m, err, errlen) || read_scalar(g, "n", &n, err, errlen) ||
        read_scalar(g, "nz", &nz, err, errlen))
        goto done;
    if (m < 0 || n < 0) {
        set_err(err, errlen, "matrix '%s': negative size %lld x %lld", name, m, n);
        goto done;
    }
    p = (int64_t *)read_dataset(g, "p", H5T_NATIVE_INT64, sizeof(int64_t), &lp, err, errlen);
    idx = (int64_t *)read_dataset(g, "i", H5T_NATIVE_INT64, sizeof(int64_t), &li, err, errlen);
    x = (double *)read_dataset(g, "x", H5T_NATIVE_DOUBLE, sizeof(double), &lx, err, errlen);
    if (p == NULL || idx == NULL || x == NULL) goto done;

    snprintf(sub, sizeof sub, "matrix '%s' (%lld x %lld, nz = %lld)", name, m, n, nz);
    if (nz == -1 || nz == -2) {
        /* compressed column (p: column pointers, i: row indices) or compressed row (p: row
         * pointers, i: column indices) */
        long long outer = nz == -1 ? n : m, inner = nz == -1 ? m : n;
        long long nnz;
        if ((long long)lp < outer + 1) {
            set_err(err, errlen, "%s: %zu pointers, expected %lld", sub, lp, outer + 1);
            goto done;
        }
        nnz = p[outer];
        if (p[0] != 0 || nnz < 0 || (long long)li < nnz || (long long)lx < nnz) {
            set_err(err, errlen, "%s: bad pointers (p[0] = %lld, nnz = %lld, %zu indices)",
                    sub, (long long)p[0], nnz, li);
            goto done;
        }
        t = (triplet *)tu_calloc((size_t)nnz, sizeof(triplet));
        for (long long o = 0; o < outer; ++o) {
            if (p[o + 1] < p[o]) {
                set_err(err, errlen, "%s: pointers decrease at %lld", sub, o);
                goto done;
            }
            for (int64_t k = p[o]; k < p[o + 1]; ++k) {
                if (idx[k] < 0 || idx[k] >= inner) {
                    set_err(err, errlen, "%s: index %lld out of range at entry %lld", sub,
                            (long long)idx[k], (long long)k);
                    goto done;
                }
                t[nt].row = nz == -1 ? idx[k] : (int64_t)o;
                t[nt].col = nz == -1 ? (int64_t)o : idx[k];
                t[nt].value = x[k];
                ++nt;
            }
        }
        *encoding = (int)nz;
    } else if (nz >= 0) {
        /* triplets: i = row index, p = column index (Siconos), checked against m and n */
        if ((long long)lp < nz || (long long)li < nz || (long long)lx < nz) {
            set_err(err, errlen, "%s: fewer than nz triplets stored", sub);
            goto done;
        }
        t = (triplet *)tu_calloc((size_t)nz, sizeof(triplet));
        for (long long k = 0; k < nz; ++k) {
            if (idx[k] < 0 || idx[k] >= m || p[k] < 0 || p[k] >= n) {
                set_err(err, errlen, "%s: triplet %lld at (%lld, %lld) out of range", sub, k,
                        (long long)idx[k], (long long)p[k]);
                goto done;
            }
            t[nt].row = idx[k];
            t[nt].col = p[k];
            t[nt].value = x[k];
            ++nt;
        }
        *encoding = 0;
    } else {
        set_err(err, errlen, "%s: unknown encoding", sub);
        goto done;
    }
    triplets_to_csc(t, nt, (size_t)m, (size_t)n, a);
    rc = 0;
done:
    free(p);
    free(idx);
    free(x);
    free(t);
    H5Gclose(g);
    return rc;
}

static double *read_vector(hid_t parent, const char *name, size_t expected, char *err,
                           size_t errlen)
{
    size_t len = 0;
    double *v = (double *)read_dataset(parent, name, H5T_NATIVE_DOUBLE, sizeof(double), &len,
                                       err, errlen);
    if (v == NULL) return NULL;
    if (len != expected) {
        set_err(err, errlen, "vector '%s' has %zu entries, expected %zu", name, len, expected);
        free(v);
        return NULL;
    }
    return v;
}

void fcr_free(fcr_problem *p) { tu_problem_free(p); }

int fcr_read(const char *path, fcr_problem *out, char *err, size_t errlen)
{
    hid_t file, top = -1, vec = -1;
    size_t nmu = 0;
    int rc = -1;
    fcr_problem p;

    memset(&p, 0, sizeof p);
    memset(out, 0, sizeof(*out));
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* no HDF5 error stack printing */
    file = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) {
        set_err(err, errlen, "%s: cannot open", path);
        return -1;
    }
    if (H5Lexists(file, "fclib_global", H5P_DEFAULT) > 0) {
        p.is_global = 1;
        top = H5Gopen2(file, "fclib_global", H5P_DEFAULT);
    } else if (H5Lexists(file, "fclib_local", H5P_DEFAULT) > 0) {
        top = H5Gopen2(file, "fclib_local", H5P_DEFAULT);
    } else {
        set_err(err, errlen, "%s: neither /fclib_global nor /fclib_local", path);
        goto done;
    }
    if (top < 0 || (vec = H5Gopen2(top, "vectors", H5P_DEFAULT)) < 0) {
        set_err(err, errlen, "%s: cannot open the problem group or its vectors", path);
        goto done;
    }
    {
        long long len = dataset_len(vec, "mu");
        if (len < 0) {
            set_err(err, errlen, "%s: no mu", path);
            goto done;
        }
        nmu = (size_t)len;
    }
    p.nc = nmu;
    if (p.is_global) {
        if (read_matrix(top, "M", &p.M, &p.encoding[0], err, errlen) ||
            read_matrix(top, "H", &p.H, &p.encoding[1], err, errlen))
            goto done;
        p.n = p.M.nrows;
        if (p.M.ncols != p.n || p.H.nrows != p.n || p.H.ncols != 3 * p.nc) {
            set_err(err, errlen, "%s: inconsistent sizes M %zux%zu, H %zux%zu, %zu contacts",
                    path, p.M.nrows, p.M.ncols, p.H.nrows, p.H.ncols, p.nc);
            goto done;
        }
        p.has_joints = H5Lexists(top, "G", H5P_DEFAULT) > 0;
        if ((p.f = read_vector(vec, "f", p.n, err, errlen)) == NULL ||
            (p.w = read_vector(vec, "w", 3 * p.nc, err, errlen)) == NULL)
            goto done;
    } else {
        if (read_matrix(top, "W", &p.W, &p.encoding[0], err, errlen)) goto done;
        p.encoding[1] = 0;
        if (p.W.nrows != 3 * p.nc || p.W.ncols != 3 * p.nc) {
            set_err(err, errlen, "%s: W is %zux%zu for %zu contacts", path, p.W.nrows,
                    p.W.ncols, p.nc);
            goto done;
        }
        if ((p.q = read_vector(vec, "q", 3 * p.nc, err, errlen)) == NULL) goto done;
    }
    if ((p.mu = read_vector(vec, "mu", p.nc, err, errlen)) == NULL) goto done;
    rc = 0;
done:
    if (vec >= 0) H5Gclose(vec);
    if (top >= 0) H5Gclose(top);
    H5Fclose(file);
    if (rc == 0)
        *out = p;
    else
        fcr_free(&p);
    return rc;
}
