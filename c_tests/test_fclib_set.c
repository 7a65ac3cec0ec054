/* The whole shared FCLib set through the C API: every *.hdf5 file of FCLIB_DATA_DIR/global
 * and FCLIB_DATA_DIR/local, read by the independent reader (fclib_read.c, HDF5 C API),
 * handed to cadmm_problem_new_global / _new_local, and solved with variant "auto",
 * tolerance 1e-8 and a time limit per file.
 *
 * The library claims (README) that "auto" solves all 71 files to 1e-8; the slowest take
 * ~15 s on the project's machine. Each file gets LIMIT_SECONDS (four times that), so a busy
 * machine does not fail the test, and an iteration cap high enough never to decide.
 *
 * For each file the status is checked against the independent error e of the returned
 * answer (test_util.h, tu_check_outcome): SOLVED needs e <= 1e-8 (1 + 1e-12) + R, any other
 * status e > 1e-8 - R with every output finite; stats.error and cadmm_problem_error must
 * equal e (relative 1e-9, plus R), and the returned u must be W r + q or H^T v + w.
 * Why a slack at all: the solver stops when its own evaluation of the measure is <= 1e-8,
 * and the independent code computes the same sums in another order, so an answer the
 * library measured just below 1e-8 can come out slightly above it here. The 1e-12 relative
 * part covers the rounding of the final norms and divisions; R (tu_problem_error_roundoff,
 * printed per file, at most ~1e-11 on this set) covers the cancellation in the residuals,
 * which on the ill-conditioned files is far larger than 1e-12 relative: the library's
 * error and the independent one differ in the sixth or fifth significant digit on
 * Confeti-ex03 and LMGC_100_PR_PerioBox (|W| |r| much larger than |u|). Without R the
 * agreement checks fail on those two files although both evaluations are right to their
 * precision.
 * Then every file must be SOLVED: one that is not is named and fails the test.
 *
 * One line per file and a total are printed. The set must hold EXPECTED_GLOBAL global and
 * EXPECTED_LOCAL local files (the 71 of the README), so a partial data directory cannot pass
 * unnoticed; a missing directory exits 77 (CTest: skipped).
 *
 * Files named after LIMIT_SECONDS (as global/NAME.hdf5 or local/NAME.hdf5) are solved
 * instead of the whole set, with the same checks, and each must be there: the Valgrind
 * variant runs a few small files of each form and matrix encoding, since the whole set
 * would take hours under Valgrind.
 *
 * Usage: test_fclib_set FCLIB_DATA_DIR [LIMIT_SECONDS [FORM/FILE.hdf5 ...]] */
#include "cadmm.h"
#include "fclib_read.h"
#include "test_util.h"

#include <dirent.h>
#include <time.h>

#define TOL 1e-8
#define SLACK 1e-12 /* relative, on TOL, for SOLVED (see the header comment) */
#define AGREE 1e-9  /* stats.error against the independent error, relative */
#define DEFAULT_LIMIT_SECONDS 60.0
#define MAX_ITERATIONS 100000000u
#define EXPECTED_GLOBAL 43
#define EXPECTED_LOCAL 28
#define MAX_FILES 512

static int by_name(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* The *.hdf5 names of dir, sorted; returns their number (names are malloc'ed). */
static size_t list_files(const char *dir, char **names)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    size_t k = 0;
    if (d == NULL) return 0;
    while ((e = readdir(d)) != NULL) {
        size_t len = strlen(e->d_name);
        if (len > 5 && strcmp(e->d_name + len - 5, ".hdf5") == 0) {
            REQUIRE(k < MAX_FILES);
            names[k] = (char *)tu_calloc(len + 1, 1);
            memcpy(names[k], e->d_name, len + 1);
            ++k;
        }
    }
    closedir(d);
    qsort(names, k, sizeof names[0], by_name);
    return k;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    static const char *const subdirs[2] = {"global", "local"};
    static char *names[MAX_FILES];
    char unsolved[4096] = "";
    const char *dir = argc > 1 ? argv[1] : "../shared/data/fclib";
    double limit = argc > 2 ? atof(argv[2]) : DEFAULT_LIMIT_SECONDS;
    size_t counts[2] = {0, 0}, solved = 0, total = 0;
    double t_solve = 0.0, t0 = now();
    cadmm_settings *s = NULL;

    if (!tu_is_dir(dir)) {
        printf("SKIP: FCLib data directory '%s' not found\n", dir);
        return TU_SKIP;
    }
    REQUIRE(limit > 0.0);
    printf("cadmm %s: %s with \"auto\", tol %.0e, %g s per file\n", cadmm_version(),
           argc > 3 ? "the files named" : "the FCLib set", TOL, limit);
    REQUIRE(cadmm_settings_new(&s) == CADMM_OK);
    REQUIRE(cadmm_settings_set_variant(s, "auto") == CADMM_OK);
    REQUIRE(cadmm_settings_set_tolerance(s, TOL) == CADMM_OK);
    REQUIRE(cadmm_settings_set_time_limit(s, limit) == CADMM_OK);
    REQUIRE(cadmm_settings_set_max_iterations(s, MAX_ITERATIONS) == CADMM_OK);

    printf("%-48s %6s %5s  %-15s %9s %12s %12s %9s %8s\n", "file", "n", "nc", "status", "iter",
           "stats.error", "independent", "round-off", "seconds");
    for (int sd = 0; sd < 2; ++sd) {
        char sub[4096];
        size_t k = 0;
        tu_join(sub, sizeof sub, dir, subdirs[sd]);
        if (argc > 3) {
            /* the named files of this form, in the order given */
            size_t len = strlen(subdirs[sd]);
            for (int a = 3; a < argc; ++a) {
                if (strncmp(argv[a], subdirs[sd], len) == 0 && argv[a][len] == '/') {
                    REQUIRE(k < MAX_FILES);
                    names[k] = (char *)tu_calloc(strlen(argv[a] + len + 1) + 1, 1);
                    strcpy(names[k++], argv[a] + len + 1);
                }
            }
        } else {
            k = list_files(sub, names);
        }
        counts[sd] = k;
        for (size_t i = 0; i < k; ++i) {
            char path[4096], err[512], label[600];
            tu_problem P;
            cadmm_problem *lib = NULL;
            cadmm_result rc;
            tu_outcome o;
            snprintf(label, sizeof label, "%s/%s", subdirs[sd], names[i]);
            tu_join(path, sizeof path, sub, names[i]);
            ++total;
            if (fcr_read(path, &P, err, sizeof err) != 0) {
                TU_FAIL("%s: the independent reader failed: %s", label, err);
                snprintf(unsolved + strlen(unsolved), sizeof unsolved - strlen(unsolved),
                         " %s (unreadable)", names[i]);
                free(names[i]);
                continue;
            }
            CHECK_MSG(P.is_global == (sd == 0), "%s: a %s problem in %s/", label,
                      P.is_global ? "global" : "local", subdirs[sd]);
            if (P.has_joints) {
                /* no shared file has joints; the reader does not read G */
                TU_FAIL("%s has joints, which the independent reader does not read", label);
                fcr_free(&P);
                free(names[i]);
                continue;
            }
            rc = tu_problem_to_cadmm(&P, &lib);
            if (rc != CADMM_OK) {
                TU_FAIL("%s: building the problem failed (%d): %s", label, (int)rc,
                        cadmm_last_error());
                snprintf(unsolved + strlen(unsolved), sizeof unsolved - strlen(unsolved),
                         " %s (refused)", names[i]);
                fcr_free(&P);
                free(names[i]);
                continue;
            }
            tu_solve(&P, lib, s, &o);
            printf("%-48s %6zu %5zu  %-15s %9llu %12.4e %12.4e %9.1e %8.3f\n", label, P.n, P.nc,
                   o.solved_call ? tu_status_name(o.status) : "(call failed)",
                   (unsigned long long)o.stats.iterations, o.stats.error, o.e_ind,
                   o.solved_call ? tu_problem_error_roundoff(&P, o.r, o.v, o.lambda) : NAN,
                   o.stats.solve_seconds);
            fflush(stdout);
            tu_check_outcome(label, &P, &o, TOL, SLACK, AGREE);
            if (o.solved_call && o.status == CADMM_STATUS_SOLVED) {
                ++solved;
            } else {
                TU_FAIL("%s: not solved to %.0e within %g s (%s, independent error %.3e)",
                        label, TOL, limit,
                        o.solved_call ? tu_status_name(o.status) : o.message, o.e_ind);
                snprintf(unsolved + strlen(unsolved), sizeof unsolved - strlen(unsolved), " %s",
                         names[i]);
            }
            t_solve += o.stats.solve_seconds;
            tu_outcome_free(&o);
            cadmm_problem_free(lib);
            fcr_free(&P);
            free(names[i]);
        }
    }
    cadmm_settings_free(s);

    printf("total: %zu/%zu solved to %.0e (%zu global, %zu local), %.1f s of solves, %.1f s "
           "in all\n", solved, total, TOL, counts[0], counts[1], t_solve, now() - t0);
    if (unsolved[0] != '\0') printf("not solved:%s\n", unsolved);
    if (argc > 3) {
        CHECK_MSG(counts[0] + counts[1] == (size_t)(argc - 3),
                  "%zu of the %d files named are not global/... or local/...",
                  (size_t)(argc - 3) - counts[0] - counts[1], argc - 3);
    } else {
        CHECK_MSG(counts[0] == EXPECTED_GLOBAL && counts[1] == EXPECTED_LOCAL,
                  "the data directory holds %zu global and %zu local files, expected %d and %d",
                  counts[0], counts[1], EXPECTED_GLOBAL, EXPECTED_LOCAL);
    }
    return tu_finish("test_fclib_set");
}
