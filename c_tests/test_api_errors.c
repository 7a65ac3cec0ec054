/* The C API contract: lifecycle, every bad input, and "out-parameters are written only on
 * success". Each failing call is made with its out-parameter pre-set to a sentinel, and the
 * test checks both the exact error code and that the sentinel survived.
 *
 * Usage: test_api_errors FCLIB_DATA_DIR (the FCLib part is skipped, with a message, only
 * when that directory does not exist). */
#include "cadmm.h"
#include "test_util.h"

#include <ctype.h>
#include <stdbool.h>
#include <unistd.h>

#ifndef CADMM_TEST_HAVE_FCLIB
#define CADMM_TEST_HAVE_FCLIB 1
#endif

/* ---- sentinels ---------------------------------------------------------------------------- */

static double sentinel_storage[4]; /* suitably aligned, never dereferenced through a handle */
#define SENTINEL_PROBLEM ((cadmm_problem *)(void *)&sentinel_storage[0])
#define SENTINEL_SETTINGS ((cadmm_settings *)(void *)&sentinel_storage[1])
#define SENTINEL_SOLVER ((cadmm_solver *)(void *)&sentinel_storage[2])
#define SENTINEL_DOUBLE (-12345.678)


/* ---- a valid single-contact problem ------------------------------------------------------ */
/* M = 2 I, H = I, f = (-2, 0.2, 0), w = 0, mu = 0.5: q = f/2 = (-1, 0.1, 0) sticks, so
 * r = -f = (2, -0.2, 0), u = 0, v = 0. */

static const int64_t DIAG_COLPTR[4] = {0, 1, 2, 3};
static const int64_t DIAG_ROWIND[3] = {0, 1, 2};
static const double TWO[3] = {2.0, 2.0, 2.0};
static const double ONE[3] = {1.0, 1.0, 1.0};
static const double F3[3] = {-2.0, 0.2, 0.0};
static const double W0[3] = {0.0, 0.0, 0.0};
static const double MU[1] = {0.5};
static const double Q3[3] = {-1.0, 0.1, 0.0};
static const double HALF[3] = {0.5, 0.5, 0.5};
/* W = I / 2 for the local form (a valid one-contact Delassus matrix). */
static const cadmm_csc W_HALF_DIAG = {3, 3, DIAG_COLPTR, DIAG_ROWIND, HALF};

static cadmm_csc csc(size_t nrows, size_t ncols, const int64_t *colptr, const int64_t *rowind,
                     const double *values)
{
    cadmm_csc a;
    a.nrows = nrows;
    a.ncols = ncols;
    a.colptr = colptr;
    a.rowind = rowind;
    a.values = values;
    return a;
}

static cadmm_problem *valid_global(void)
{
    cadmm_problem *p = NULL;
    cadmm_csc M = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, TWO);
    cadmm_csc H = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONE);
    REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, F3, W0, MU, &p));
    REQUIRE(p != NULL);
    return p;
}

static cadmm_problem *valid_local(void)
{
    cadmm_problem *p = NULL;
    cadmm_csc W = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, HALF);
    REQUIRE_OK(cadmm_problem_new_local(1, &W, Q3, MU, &p));
    REQUIRE(p != NULL);
    return p;
}

static cadmm_settings *valid_settings(void)
{
    cadmm_settings *s = NULL;
    REQUIRE_OK(cadmm_settings_new(&s));
    REQUIRE(s != NULL);
    return s;
}

/* ---- detailed messages (cadmm_last_error, cadmm_solver_last_error) --------------------- */

/* The message the priming call leaves (a copy): a later check must see another one, so a
 * call that forgets to record its failure cannot pass on an older message. */
static char primed_message[512];

/* A problem kept for prime_last_error (freed at the end of main). */
static cadmm_problem *primer_problem = NULL;

/* Makes a known call fail, so that this thread's last error is a known message that no
 * other check expects ("n_velocities is NULL" or similar). */
static void prime_last_error(void)
{
    size_t nc;
    bool g;
    if (primer_problem == NULL) {
        static const int64_t colptr[4] = {0, 1, 2, 3}, rowind[3] = {0, 1, 2};
        static const double ones[3] = {1.0, 1.0, 1.0}, q[3] = {-1.0, 0.0, 0.0}, mu[1] = {0.5};
        cadmm_csc W = {3, 3, colptr, rowind, ones};
        REQUIRE(cadmm_problem_new_local(1, &W, q, mu, &primer_problem) == CADMM_OK);
    }
    REQUIRE(cadmm_problem_dims(primer_problem, NULL, &nc, &g) == CADMM_ERR_NULL_POINTER);
    snprintf(primed_message, sizeof primed_message, "%s", cadmm_last_error());
    REQUIRE(primed_message[0] != '\0');
}

/* Case-insensitive strstr. */
static const char *find_ci(const char *text, const char *needle)
{
    size_t n = strlen(needle);
    for (const char *p = text; *p != '\0'; ++p) {
        size_t k = 0;
        while (k < n && p[k] != '\0' &&
               tolower((unsigned char)p[k]) == tolower((unsigned char)needle[k]))
            ++k;
        if (k == n) return p;
    }
    return n == 0 ? text : NULL;
}

/* Checks that `msg` (a failed call's detailed message) is not the primed one (when
 * `fresh`), names every word of `words` (space-separated; each as a whole word, e.g. the
 * matrix "M", the setting "tolerance") and contains every phrase of `phrases`
 * ('|'-separated, case-insensitive: the fault, e.g. "out of range"). NULL lists check
 * nothing. */
static void check_message(const char *what, const char *msg, int fresh, const char *words,
                          const char *phrases)
{
    char buf[256];
    if (msg == NULL) {
        TU_FAIL("[%s] the message is NULL", what);
        return;
    }
    if (fresh && strcmp(msg, primed_message) == 0) {
        TU_FAIL("[%s] the failed call did not record its own message (still \"%s\")", what, msg);
        return;
    }
    if (words != NULL) {
        snprintf(buf, sizeof buf, "%s", words);
        for (char *w = strtok(buf, " "); w != NULL; w = strtok(NULL, " "))
            CHECK_MSG(tu_has_word(msg, w), "[%s] message \"%s\" does not name '%s'", what, msg, w);
    }
    if (phrases != NULL) {
        snprintf(buf, sizeof buf, "%s", phrases);
        for (char *f = strtok(buf, "|"); f != NULL; f = strtok(NULL, "|"))
            CHECK_MSG(find_ci(msg, f) != NULL, "[%s] message \"%s\" does not say \"%s\"", what,
                      msg, f);
    }
}

/* cadmm_last_error() after a failed call made since prime_last_error(). */
static void expect_last_error(const char *what, const char *words, const char *phrases)
{
    check_message(what, cadmm_last_error(), 1, words, phrases);
}

/* new_global with its out-parameter pre-set to the sentinel; on failure the thread's
 * detailed message must name `words` and say `phrases` (see check_message). */
static void global_fails(const char *what, const char *words, const char *phrases,
                         cadmm_result expected, size_t n, size_t nc, const cadmm_csc *M,
                         const cadmm_csc *H, const double *f, const double *w, const double *mu)
{
    cadmm_problem *p = SENTINEL_PROBLEM;
    cadmm_result rc;
    prime_last_error();
    rc = cadmm_problem_new_global(n, nc, M, H, f, w, mu, &p);
    CHECK_MSG(rc == expected, "new_global [%s]: %s, expected %s (%s)", what, tu_result_name(rc),
              tu_result_name(expected), rc == CADMM_OK ? "" : cadmm_last_error());
    if (expected != CADMM_OK) {
        CHECK_MSG(p == SENTINEL_PROBLEM, "new_global [%s]: out-parameter overwritten", what);
        if (rc == expected) check_message(what, cadmm_last_error(), 1, words, phrases);
    } else {
        CHECK_MSG(p != SENTINEL_PROBLEM && p != NULL, "new_global [%s]: no problem returned", what);
        /* a success leaves the last message alone */
        CHECK_MSG(strcmp(cadmm_last_error(), primed_message) == 0,
                  "new_global [%s]: a success changed cadmm_last_error to \"%s\"", what,
                  cadmm_last_error());
    }
    if (rc == CADMM_OK && p != SENTINEL_PROBLEM) cadmm_problem_free(p);
}

static void local_fails(const char *what, const char *words, const char *phrases,
                        cadmm_result expected, size_t nc, const cadmm_csc *W, const double *q,
                        const double *mu)
{
    cadmm_problem *p = SENTINEL_PROBLEM;
    cadmm_result rc;
    prime_last_error();
    rc = cadmm_problem_new_local(nc, W, q, mu, &p);
    CHECK_MSG(rc == expected, "new_local [%s]: %s, expected %s (%s)", what, tu_result_name(rc),
              tu_result_name(expected), rc == CADMM_OK ? "" : cadmm_last_error());
    if (expected != CADMM_OK) {
        CHECK_MSG(p == SENTINEL_PROBLEM, "new_local [%s]: out-parameter overwritten", what);
        if (rc == expected) check_message(what, cadmm_last_error(), 1, words, phrases);
    } else {
        CHECK_MSG(p != SENTINEL_PROBLEM && p != NULL, "new_local [%s]: no problem returned", what);
    }
    if (rc == CADMM_OK && p != SENTINEL_PROBLEM) cadmm_problem_free(p);
}

/* A call that must fail with `expected` and a fresh thread message naming `words` and
 * saying `phrases` (see check_message). */
#define FAILS_WITH(expr, expected, words, phrases)                                     \
    do {                                                                                  \
        prime_last_error();                                                               \
        EXPECT_RC(expr, expected);                                                        \
        expect_last_error(#expr, words, phrases);                                         \
    } while (0)

/* ---- version, messages, free(NULL) -------------------------------------------------------- */

static void test_basics(void)
{
    /* the fault each code's message must name (case-insensitive) */
    static const char *const keyword[] = {
        "ok",      "NULL",     "dimension", "sparse column", "value", "positive definite",
        "singular", "setting", "i/o",       "unsupported",   "panic", "pattern",
        "memory",
    };
    const char *v = cadmm_version();
#ifndef CADMM_VERSION_STRING
#error "cadmm.h must define CADMM_VERSION_STRING"
#endif
    CHECK_MSG(v != NULL && strcmp(v, CADMM_VERSION_STRING) == 0,
              "cadmm_version() = %s, header says %s", v ? v : "(null)", CADMM_VERSION_STRING);
    REQUIRE(sizeof keyword / sizeof keyword[0] == (size_t)CADMM_ERR_OUT_OF_MEMORY + 1);
    for (int c = CADMM_OK; c <= CADMM_ERR_OUT_OF_MEMORY; ++c) {
        const char *m = cadmm_result_message(c);
        if (m == NULL) {
            TU_FAIL("no message for code %d", c);
            continue;
        }
        CHECK_MSG(find_ci(m, keyword[c]) != NULL, "message of %s is \"%s\": it does not say \"%s\"",
                  tu_result_name(c), m, keyword[c]);
        CHECK_MSG(find_ci(m, "unknown") == NULL, "code %d is unknown: %s", c, m);
        for (int d = CADMM_OK; d < c; ++d)
            CHECK_MSG(strcmp(m, cadmm_result_message(d)) != 0,
                      "codes %d and %d share the message %s",
                      d, c, m);
    }
    /* a value that is not a code: the "unknown" message, the same for every such value */
    CHECK(cadmm_result_message(-1) != NULL && find_ci(cadmm_result_message(-1), "unknown") != NULL);
    CHECK(cadmm_result_message(999) != NULL &&
          strcmp(cadmm_result_message(999), cadmm_result_message(-1)) == 0);
    CHECK(CADMM_STATUS_SOLVED == 0);
    CHECK(CADMM_OK == 0);
    /* _free(NULL) is a no-op */
    cadmm_problem_free(NULL);
    cadmm_settings_free(NULL);
    cadmm_solver_free(NULL);
    /* a NULL solver: a static message that says so */
    check_message("cadmm_solver_last_error(NULL)", cadmm_solver_last_error(NULL), 0, NULL, "NULL");
    CHECK(cadmm_solver_trace_len(NULL) == 0);
    /* the thread's last error: a NULL out-parameter is named */
    prime_last_error();
    EXPECT_RC(cadmm_settings_new(NULL), CADMM_ERR_NULL_POINTER);
    expect_last_error("cadmm_settings_new(NULL)", "out", "NULL");
}

/* ---- problem construction ----------------------------------------------------------------- */

static void test_global_inputs(void)
{
    cadmm_csc M = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, TWO);
    cadmm_csc H = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONE);
    double bad[3];
    double mu_bad;

    /* the valid problem, as a control */
    global_fails("valid", NULL, NULL, CADMM_OK, 3, 1, &M, &H, F3, W0, MU);

    /* NULL pointers */
    global_fails("M NULL", "M", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, NULL, &H, F3, W0, MU);
    global_fails("H NULL", "H", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &M, NULL, F3, W0, MU);
    global_fails("f NULL", "f", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &M, &H, NULL, W0, MU);
    global_fails("w NULL", "w", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &M, &H, F3, NULL, MU);
    global_fails("mu NULL", "mu", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &M, &H, F3, W0, NULL);
    FAILS_WITH(cadmm_problem_new_global(3, 1, &M, &H, F3, W0, MU, NULL), CADMM_ERR_NULL_POINTER,
               "out", "NULL");
    {
        cadmm_csc Mnull = csc(3, 3, NULL, DIAG_ROWIND, TWO);
        global_fails("M.colptr NULL", "M colptr", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &Mnull, &H,
                     F3, W0, MU);
        Mnull = csc(3, 3, DIAG_COLPTR, NULL, TWO);
        global_fails("M.rowind NULL", "M rowind", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &Mnull, &H,
                     F3, W0, MU);
        Mnull = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, NULL);
        global_fails("M.values NULL", "M values", "NULL", CADMM_ERR_NULL_POINTER, 3, 1, &Mnull, &H,
                     F3, W0, MU);
    }

    /* wrong dimensions */
    {
        static const double f4[4] = {0, 0, 0, 0}, w6[6] = {0}, mu2[2] = {0.5, 0.5};
        cadmm_csc M32 = csc(3, 2, DIAG_COLPTR, DIAG_ROWIND, TWO); /* 3 x 2 */
        cadmm_csc H32 = csc(3, 2, DIAG_COLPTR, DIAG_ROWIND, ONE); /* 3 x 2, not 3 nc */
        cadmm_csc H43 = csc(4, 3, DIAG_COLPTR, DIAG_ROWIND, ONE); /* 4 rows for n = 3 */
        global_fails("n = 4, M 3x3", "M 3 4", "expected", CADMM_ERR_DIMENSION, 4, 1, &M, &H, f4,
                     W0, MU);
        global_fails("M 3x2", "M 2 3", "expected", CADMM_ERR_DIMENSION, 3, 1, &M32, &H, F3, W0, MU);
        global_fails("H 3x2", "H 2 3", "expected", CADMM_ERR_DIMENSION, 3, 1, &M, &H32, F3, W0, MU);
        global_fails("H 4x3", "H 3 4", "expected", CADMM_ERR_DIMENSION, 3, 1, &M, &H43, F3, W0, MU);
        global_fails("nc = 2, H 3x3", "H 3 6", "expected", CADMM_ERR_DIMENSION, 3, 2, &M, &H, F3,
                     w6, mu2);
    }

    /* corrupt CSC, in M and in H */
    {
        static const int64_t decreasing[4] = {0, 2, 1, 3};
        static const int64_t start1[4] = {1, 1, 2, 3};
        static const int64_t negptr[4] = {0, -1, 2, 3};
        static const int64_t row_oob[3] = {0, 3, 2};
        static const int64_t row_neg[3] = {0, -1, 2};
        static const int64_t dup_colptr[4] = {0, 2, 3, 4};
        static const int64_t dup_rowind[4] = {0, 0, 1, 2};
        static const double dup_values[4] = {1.0, 1.0, 2.0, 2.0};
        cadmm_csc a;
        a = csc(3, 3, decreasing, DIAG_ROWIND, TWO);
        global_fails("M colptr decreasing", "M", "decrease|column 1", CADMM_ERR_INVALID_CSC, 3, 1,
                     &a, &H, F3, W0, MU);
        global_fails("H colptr decreasing", "H", "decrease|column 1", CADMM_ERR_INVALID_CSC, 3, 1,
                     &M, &a, F3, W0, MU);
        a = csc(3, 3, start1, DIAG_ROWIND, TWO);
        global_fails("M colptr[0] = 1", "M colptr", "expected 0", CADMM_ERR_INVALID_CSC, 3, 1, &a,
                     &H, F3, W0, MU);
        a = csc(3, 3, negptr, DIAG_ROWIND, TWO);
        global_fails("M colptr negative", "M colptr", "negative", CADMM_ERR_INVALID_CSC, 3, 1, &a,
                     &H, F3, W0, MU);
        a = csc(3, 3, DIAG_COLPTR, row_oob, TWO);
        global_fails("M row index out of range", "M", "row index|out of range|column 1",
                     CADMM_ERR_INVALID_CSC, 3, 1, &a, &H, F3, W0, MU);
        global_fails("H row index out of range", "H", "row index|out of range|column 1",
                     CADMM_ERR_INVALID_CSC, 3, 1, &M, &a, F3, W0, MU);
        a = csc(3, 3, DIAG_COLPTR, row_neg, TWO);
        global_fails("M negative row index", "M", "row index|negative", CADMM_ERR_INVALID_CSC, 3,
                     1, &a, &H, F3, W0, MU);
        global_fails("H negative row index", "H", "row index|negative", CADMM_ERR_INVALID_CSC, 3,
                     1, &M, &a, F3, W0, MU);
        a = csc(3, 3, dup_colptr, dup_rowind, dup_values);
        global_fails("M duplicate entry", "M", "duplicate|column 0", CADMM_ERR_INVALID_CSC, 3, 1,
                     &a, &H, F3, W0, MU);
        global_fails("H duplicate entry", "H", "duplicate|column 0", CADMM_ERR_INVALID_CSC, 3, 1,
                     &M, &a, F3, W0, MU);
    }

    /* issue 41, a hostile caller: sizes that contradict each other are refused before
     * anything sized by them is allocated or read (1e12 contacts aborted on copying w), and
     * column pointers past the 3 entries the arrays hold are refused before rowind and
     * values are read (a heap overflow at colptr[3] = 40, a crash at 1e18). */
    {
        static const int64_t past40[4] = {0, 1, 2, 40};
        static const int64_t past1e18[4] = {0, 1, 2, INT64_C(1000000000000000000)};
        static const int64_t crowded[4] = {0, 4, 4, 4};
        const size_t many = (size_t)UINT64_C(1000000000000);
        const size_t wide = (size_t)1 << 40;
        cadmm_csc a;
        global_fails("n_contacts = 1e12, H 3x3", "H 3 3000000000000", "expected",
                     CADMM_ERR_DIMENSION, 3, many, &M, &H, F3, W0, MU);
        local_fails("n_contacts = 1e12, W 3x3", "W 3 3000000000000", "expected",
                    CADMM_ERR_DIMENSION, many, &W_HALF_DIAG, Q3, MU);
        a = csc(3, wide, DIAG_COLPTR, DIAG_ROWIND, TWO);
        global_fails("M ncols = 2^40", "M 3 1099511627776", "expected", CADMM_ERR_DIMENSION, 3,
                     1, &a, &H, F3, W0, MU);
        a = csc(3, wide, DIAG_COLPTR, DIAG_ROWIND, ONE);
        global_fails("H ncols = 2^40", "H 3 1099511627776", "expected", CADMM_ERR_DIMENSION, 3,
                     1, &M, &a, F3, W0, MU);
        a = csc(3, 3, past40, DIAG_ROWIND, TWO);
        global_fails("M colptr[3] = 40", "M 40 9", "at most", CADMM_ERR_INVALID_CSC, 3, 1, &a,
                     &H, F3, W0, MU);
        global_fails("H colptr[3] = 40", "H 40 9", "at most", CADMM_ERR_INVALID_CSC, 3, 1, &M,
                     &a, F3, W0, MU);
        a = csc(3, 3, past1e18, DIAG_ROWIND, TWO);
        global_fails("M colptr[3] = 1e18", "M 1000000000000000000", "at most",
                     CADMM_ERR_INVALID_CSC, 3, 1, &a, &H, F3, W0, MU);
        local_fails("W colptr[3] = 1e18", "W 1000000000000000000", "at most",
                    CADMM_ERR_INVALID_CSC, 1, &a, Q3, MU);
        a = csc(3, 3, crowded, DIAG_ROWIND, TWO);
        global_fails("M column 0 with 4 entries", "M 0 4", "more than nrows",
                     CADMM_ERR_INVALID_CSC, 3, 1, &a, &H, F3, W0, MU);
    }

    /* non-finite values */
    {
        double mvals[3] = {2.0, NAN, 2.0}, hvals[3] = {1.0, 1.0, INFINITY};
        cadmm_csc Mnan = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, mvals);
        cadmm_csc Hinf = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, hvals);
        global_fails("NaN in M", "M", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &Mnan, &H, F3, W0,
                     MU);
        global_fails("Inf in H", "H", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &Hinf, F3, W0,
                     MU);
        memcpy(bad, F3, sizeof bad);
        bad[1] = NAN;
        global_fails("NaN in f", "f", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, bad, W0, MU);
        bad[1] = -INFINITY;
        global_fails("-Inf in f", "f", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, bad, W0,
                     MU);
        memcpy(bad, W0, sizeof bad);
        bad[2] = INFINITY;
        global_fails("Inf in w", "w", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, F3, bad, MU);
    }

    /* friction coefficients */
    mu_bad = -0.1;
    global_fails("negative mu", "mu", "negative", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, F3, W0,
                 &mu_bad);
    mu_bad = NAN;
    global_fails("NaN mu", "mu", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, F3, W0, &mu_bad);
    mu_bad = INFINITY;
    global_fails("Inf mu", "mu", "finite", CADMM_ERR_INVALID_VALUE, 3, 1, &M, &H, F3, W0, &mu_bad);
    mu_bad = 0.0; /* frictionless is valid */
    global_fails("mu = 0", NULL, NULL, CADMM_OK, 3, 1, &M, &H, F3, W0, &mu_bad);
}

static void test_local_inputs(void)
{
    cadmm_csc W = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, HALF);
    double bad[3], mu_bad;
    local_fails("valid", NULL, NULL, CADMM_OK, 1, &W, Q3, MU);

    local_fails("W NULL", "W", "NULL", CADMM_ERR_NULL_POINTER, 1, NULL, Q3, MU);
    local_fails("q NULL", "q", "NULL", CADMM_ERR_NULL_POINTER, 1, &W, NULL, MU);
    local_fails("mu NULL", "mu", "NULL", CADMM_ERR_NULL_POINTER, 1, &W, Q3, NULL);
    FAILS_WITH(cadmm_problem_new_local(1, &W, Q3, MU, NULL), CADMM_ERR_NULL_POINTER, "out", "NULL");

    {
        static const double q6[6] = {0}, mu2[2] = {0.5, 0.5};
        cadmm_csc W32 = csc(3, 2, DIAG_COLPTR, DIAG_ROWIND, HALF);
        local_fails("nc = 2, W 3x3", "W 3 6", "expected", CADMM_ERR_DIMENSION, 2, &W, q6, mu2);
        local_fails("W 3x2", "W 2 3", "expected", CADMM_ERR_DIMENSION, 1, &W32, Q3, MU);
    }
    {
        static const int64_t decreasing[4] = {0, 2, 1, 3};
        static const int64_t row_oob[3] = {0, 1, 7};
        static const int64_t row_neg[3] = {-5, 1, 2};
        static const int64_t dup_colptr[4] = {0, 1, 3, 4};
        static const int64_t dup_rowind[4] = {0, 1, 1, 2};
        static const double dup_values[4] = {1.0, 1.0, 1.0, 1.0};
        cadmm_csc a;
        a = csc(3, 3, decreasing, DIAG_ROWIND, HALF);
        local_fails("W colptr decreasing", "W", "decrease|column 1", CADMM_ERR_INVALID_CSC, 1, &a,
                    Q3, MU);
        a = csc(3, 3, DIAG_COLPTR, row_oob, HALF);
        local_fails("W row index out of range", "W", "row index|out of range|column 2",
                    CADMM_ERR_INVALID_CSC, 1, &a, Q3, MU);
        a = csc(3, 3, DIAG_COLPTR, row_neg, HALF);
        local_fails("W negative row index", "W", "row index|negative", CADMM_ERR_INVALID_CSC, 1,
                    &a, Q3, MU);
        a = csc(3, 3, dup_colptr, dup_rowind, dup_values);
        local_fails("W duplicate entry", "W", "duplicate|column 1", CADMM_ERR_INVALID_CSC, 1, &a,
                    Q3, MU);
    }
    {
        double wvals[3] = {0.5, 0.5, NAN};
        cadmm_csc Wnan = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, wvals);
        local_fails("NaN in W", "W", "finite", CADMM_ERR_INVALID_VALUE, 1, &Wnan, Q3, MU);
        wvals[2] = INFINITY;
        local_fails("Inf in W", "W", "finite", CADMM_ERR_INVALID_VALUE, 1, &Wnan, Q3, MU);
        memcpy(bad, Q3, sizeof bad);
        bad[0] = NAN;
        local_fails("NaN in q", "q", "finite", CADMM_ERR_INVALID_VALUE, 1, &W, bad, MU);
    }
    mu_bad = -1.0;
    local_fails("negative mu", "mu", "negative", CADMM_ERR_INVALID_VALUE, 1, &W, Q3, &mu_bad);
    mu_bad = NAN;
    local_fails("NaN mu", "mu", "finite", CADMM_ERR_INVALID_VALUE, 1, &W, Q3, &mu_bad);
}

/* problem_error and problem_dims */
static void test_problem_queries(void)
{
    cadmm_problem *g = valid_global(), *l = valid_local();
    const double r[3] = {2.0, -0.2, 0.0}, u[3] = {0, 0, 0}, v[3] = {0, 0, 0};
    double e = SENTINEL_DOUBLE;
    size_t n = 777, nc = 777;
    bool is_global = true;

    EXPECT_RC(cadmm_problem_error(NULL, r, u, v, &e), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_error(g, NULL, u, v, &e), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_error(g, r, u, NULL, &e), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_error(g, r, u, v, NULL), CADMM_ERR_NULL_POINTER);
    CHECK_MSG(e == SENTINEL_DOUBLE, "problem_error wrote *error on failure");
    /* the exact solution has zero error; u and (for a local problem) v may be NULL */
    EXPECT_RC(cadmm_problem_error(g, r, NULL, v, &e), CADMM_OK);
    CHECK_MSG(e >= 0.0 && e <= 1e-15, "error of the exact global solution: %g", e);
    e = SENTINEL_DOUBLE;
    EXPECT_RC(cadmm_problem_error(l, r, NULL, NULL, &e), CADMM_OK);
    CHECK_MSG(e >= 0.0 && e <= 1e-15, "error of the exact local solution: %g", e);
    /* a non-finite candidate has an infinite error, and the call succeeds */
    {
        double rn[3] = {NAN, 0, 0};
        EXPECT_RC(cadmm_problem_error(l, rn, NULL, NULL, &e), CADMM_OK);
        CHECK_MSG(isinf(e) && e > 0, "error of a NaN candidate: %g", e);
    }

    EXPECT_RC(cadmm_problem_dims(NULL, &n, &nc, &is_global), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_dims(g, NULL, &nc, &is_global), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_dims(g, &n, NULL, &is_global), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_dims(g, &n, &nc, NULL), CADMM_ERR_NULL_POINTER);
    CHECK_MSG(n == 777 && nc == 777 && is_global, "problem_dims wrote outputs on failure");
    EXPECT_RC(cadmm_problem_dims(g, &n, &nc, &is_global), CADMM_OK);
    CHECK(n == 3 && nc == 1 && is_global);
    EXPECT_RC(cadmm_problem_dims(l, &n, &nc, &is_global), CADMM_OK);
    CHECK(n == 0 && nc == 1 && !is_global);

    cadmm_problem_free(g);
    cadmm_problem_free(l);
}

/* joints (G^T v + b = 0) */
static void test_joints(void)
{
    cadmm_problem *g = valid_global(), *l = valid_local();
    /* G = e_2 (3 x 1): v_2 = -b */
    static const int64_t gcol[2] = {0, 1}, grow[1] = {2};
    static const double gval[1] = {1.0};
    const double b[1] = {0.0};
    double bnan[1] = {NAN};
    cadmm_csc G = csc(3, 1, gcol, grow, gval);
    cadmm_csc G4 = csc(4, 1, gcol, grow, gval);

    FAILS_WITH(cadmm_problem_set_joints(NULL, &G, b), CADMM_ERR_NULL_POINTER, "p", "NULL");
    FAILS_WITH(cadmm_problem_set_joints(g, NULL, b), CADMM_ERR_NULL_POINTER, "G", "NULL");
    FAILS_WITH(cadmm_problem_set_joints(g, &G, NULL), CADMM_ERR_NULL_POINTER, "b", "NULL");
    FAILS_WITH(cadmm_problem_set_joints(g, &G4, b), CADMM_ERR_DIMENSION, "G 3 4", "expected");
    FAILS_WITH(cadmm_problem_set_joints(g, &G, bnan), CADMM_ERR_INVALID_VALUE, "b", "finite");
    FAILS_WITH(cadmm_problem_set_joints(l, &G, b), CADMM_ERR_UNSUPPORTED, NULL, "joints|global");

    /* a valid joint on the sticking problem: v_2 is already 0 at the solution */
    EXPECT_RC(cadmm_problem_set_joints(g, &G, b), CADMM_OK);
    {
        cadmm_settings *s = valid_settings();
        cadmm_solver *sv = NULL;
        cadmm_status st = -1;
        double r[3], v[3];
        REQUIRE_OK(cadmm_settings_set_tolerance(s, 1e-10));
        EXPECT_RC(cadmm_solver_new(g, s, &sv), CADMM_OK);
        if (sv) {
            EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
            CHECK_MSG(st == CADMM_STATUS_SOLVED, "joint problem: status %d", st);
            EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, v), CADMM_OK);
            CHECK_MSG(fabs(v[2]) <= 1e-8, "joint violated: v_2 = %g", v[2]);
            CHECK_MSG(fabs(r[0] - 2.0) <= 1e-6 && fabs(r[1] + 0.2) <= 1e-6 && fabs(r[2]) <= 1e-6,
                      "joint problem: r = (%g, %g, %g), expected (2, -0.2, 0)", r[0], r[1], r[2]);
        }
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
    }
    /* a G without columns removes the joints */
    {
        static const int64_t c0[1] = {0};
        cadmm_csc G0 = csc(3, 0, c0, NULL, NULL);
        EXPECT_RC(cadmm_problem_set_joints(g, &G0, NULL), CADMM_OK);
    }
    cadmm_problem_free(g);
    cadmm_problem_free(l);
}

/* ---- settings ------------------------------------------------------------------------------ */

static void test_settings(void)
{
    cadmm_settings *s = SENTINEL_SETTINGS;
    FAILS_WITH(cadmm_settings_new(NULL), CADMM_ERR_NULL_POINTER, "out", "NULL");
    s = valid_settings();

    FAILS_WITH(cadmm_settings_set_variant(NULL, "auto"), CADMM_ERR_NULL_POINTER, "s", "NULL");
    FAILS_WITH(cadmm_settings_set_variant(s, NULL), CADMM_ERR_NULL_POINTER, "name", "NULL");
    {
        static const char *const bad[] = {"", "bogus", "AUTO", "cp", "cp-X", "cp-N-He", "vp-N",
                                          "vp-N-he", "vp-RRR-He", "vp-N-Spectral-"};
        for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
            char quoted[64];
            cadmm_result rc;
            prime_last_error();
            rc = cadmm_settings_set_variant(s, bad[i]);
            CHECK_MSG(rc == CADMM_ERR_INVALID_SETTING, "set_variant(\"%s\"): %s", bad[i],
                      tu_result_name(rc));
            /* the message names the setting, says the name is unknown, and quotes it */
            snprintf(quoted, sizeof quoted, "unknown|'%s'", bad[i]);
            expect_last_error(bad[i], "variant", quoted);
        }
        static const char *const good[] = {"auto", "cp-N", "cp-R", "cp-RR", "vp-N-He",
                                           "vp-R-He", "vp-RR-He", "vp-N-Wohlberg",
                                           "vp-R-Wohlberg", "vp-RR-Wohlberg", "vp-N-Spectral",
                                           "vp-R-Spectral", "vp-RR-Spectral"};
        for (size_t i = 0; i < sizeof good / sizeof good[0]; ++i) {
            cadmm_result rc = cadmm_settings_set_variant(s, good[i]);
            CHECK_MSG(rc == CADMM_OK, "set_variant(\"%s\"): %s", good[i], tu_result_name(rc));
        }
    }

    FAILS_WITH(cadmm_settings_set_tolerance(NULL, 1e-8), CADMM_ERR_NULL_POINTER, "s", "NULL");
    FAILS_WITH(cadmm_settings_set_tolerance(s, 0.0), CADMM_ERR_INVALID_SETTING, "tolerance",
               "positive");
    FAILS_WITH(cadmm_settings_set_tolerance(s, -1e-8), CADMM_ERR_INVALID_SETTING, "tolerance",
               "positive");
    FAILS_WITH(cadmm_settings_set_tolerance(s, NAN), CADMM_ERR_INVALID_SETTING, "tolerance",
               "finite");
    FAILS_WITH(cadmm_settings_set_tolerance(s, INFINITY), CADMM_ERR_INVALID_SETTING, "tolerance",
               "finite");
    EXPECT_RC(cadmm_settings_set_tolerance(s, 1e-6), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_max_iterations(NULL, 10), CADMM_ERR_NULL_POINTER);
    FAILS_WITH(cadmm_settings_set_max_iterations(s, 0), CADMM_ERR_INVALID_SETTING, "max_iterations",
               "at least 1");
    EXPECT_RC(cadmm_settings_set_max_iterations(s, 1000), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_time_limit(NULL, 1.0), CADMM_ERR_NULL_POINTER);
    FAILS_WITH(cadmm_settings_set_time_limit(s, 0.0), CADMM_ERR_INVALID_SETTING, "time_limit",
               "positive");
    FAILS_WITH(cadmm_settings_set_time_limit(s, -1.0), CADMM_ERR_INVALID_SETTING, "time_limit",
               "positive");
    FAILS_WITH(cadmm_settings_set_time_limit(s, NAN), CADMM_ERR_INVALID_SETTING, "time_limit",
               "positive");
    EXPECT_RC(cadmm_settings_set_time_limit(s, INFINITY), CADMM_OK);
    EXPECT_RC(cadmm_settings_set_time_limit(s, 10.0), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_initial_rho(NULL, "normal", 1.0), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_settings_set_initial_rho(s, NULL, 1.0), CADMM_ERR_NULL_POINTER);
    FAILS_WITH(cadmm_settings_set_initial_rho(s, "bogus", 1.0), CADMM_ERR_INVALID_SETTING,
               "initial_rho",
               "bogus");
    FAILS_WITH(cadmm_settings_set_initial_rho(s, "Normal", 1.0), CADMM_ERR_INVALID_SETTING,
               "initial_rho",
               "Normal");
    FAILS_WITH(cadmm_settings_set_initial_rho(s, "given", 0.0), CADMM_ERR_INVALID_SETTING,
               "initial_rho",
               "positive");
    EXPECT_RC(cadmm_settings_set_initial_rho(s, "given", -2.0), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_initial_rho(s, "given", NAN), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_initial_rho(s, "given", INFINITY), CADMM_ERR_INVALID_SETTING);
    {
        static const char *const rules[] = {"normal", "acary", "ghadimi", "dicairano"};
        for (int i = 0; i < 4; ++i)
            EXPECT_RC(cadmm_settings_set_initial_rho(s, rules[i], NAN), CADMM_OK); /* rho ignored */
    }
    EXPECT_RC(cadmm_settings_set_initial_rho(s, "given", 3.0), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_anderson(NULL, 0), CADMM_ERR_NULL_POINTER);
    FAILS_WITH(cadmm_settings_set_anderson(s, 65), CADMM_ERR_INVALID_SETTING, "anderson 64 65",
               NULL);
    EXPECT_RC(cadmm_settings_set_anderson(s, 4000000000u), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_anderson(s, 64), CADMM_OK);
    EXPECT_RC(cadmm_settings_set_anderson(s, 0), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_s_update(NULL, "internal"), CADMM_ERR_NULL_POINTER);
    FAILS_WITH(cadmm_settings_set_s_update(s, NULL), CADMM_ERR_NULL_POINTER, "mode", "NULL");
    FAILS_WITH(cadmm_settings_set_s_update(s, "bogus"), CADMM_ERR_INVALID_SETTING, "s_update",
               "bogus");
    EXPECT_RC(cadmm_settings_set_s_update(s, ""), CADMM_ERR_INVALID_SETTING);
    EXPECT_RC(cadmm_settings_set_s_update(s, "external"), CADMM_OK);
    EXPECT_RC(cadmm_settings_set_s_update(s, "internal"), CADMM_OK);

    EXPECT_RC(cadmm_settings_set_trace(NULL, true), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_settings_set_trace(s, true), CADMM_OK);
    EXPECT_RC(cadmm_settings_set_trace(s, false), CADMM_OK);
    cadmm_settings_free(s);

    /* A rejected value leaves the settings unchanged: max_iterations stays 1. */
    {
        cadmm_problem *p = valid_local();
        cadmm_solver *sv = NULL;
        cadmm_status st = -1;
        cadmm_stats stats;
        s = valid_settings();
        EXPECT_RC(cadmm_settings_set_max_iterations(s, 1), CADMM_OK);
        EXPECT_RC(cadmm_settings_set_tolerance(s, 1e-14), CADMM_OK);
        EXPECT_RC(cadmm_settings_set_max_iterations(s, 0), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_tolerance(s, NAN), CADMM_ERR_INVALID_SETTING);
        EXPECT_RC(cadmm_settings_set_variant(s, "nope"), CADMM_ERR_INVALID_SETTING);
        REQUIRE_OK(cadmm_solver_new(p, s, &sv));
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        memset(&stats, 0, sizeof stats);
        stats.struct_size = sizeof stats;
        EXPECT_RC(cadmm_solver_get_stats(sv, &stats), CADMM_OK);
        CHECK_MSG(st == CADMM_STATUS_MAX_ITERATIONS && stats.iterations == 1,
                  "max_iterations = 1 not kept: status %d after %llu iterations", st,
                  (unsigned long long)stats.iterations);
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

/* ---- solver ---------------------------------------------------------------------------------- */

static void solver_new_fails(const char *what, const char *words, const char *phrases,
                             cadmm_result expected, const cadmm_problem *p,
                             const cadmm_settings *s)
{
    cadmm_solver *sv = SENTINEL_SOLVER;
    cadmm_result rc;
    prime_last_error();
    rc = cadmm_solver_new(p, s, &sv);
    CHECK_MSG(rc == expected, "solver_new [%s]: %s, expected %s", what, tu_result_name(rc),
              tu_result_name(expected));
    CHECK_MSG(sv == SENTINEL_SOLVER, "solver_new [%s]: out-parameter overwritten", what);
    if (rc == expected) check_message(what, cadmm_last_error(), 1, words, phrases);
    if (rc == CADMM_OK && sv != SENTINEL_SOLVER) cadmm_solver_free(sv);
}

static void test_solver_new_failures(void)
{
    cadmm_problem *p = valid_global();
    cadmm_settings *s = valid_settings();
    solver_new_fails("problem NULL", "p", "NULL", CADMM_ERR_NULL_POINTER, NULL, s);
    solver_new_fails("settings NULL", "s", "NULL", CADMM_ERR_NULL_POINTER, p, NULL);
    FAILS_WITH(cadmm_solver_new(p, s, NULL), CADMM_ERR_NULL_POINTER, "out", "NULL");

    /* indefinite and singular M: accepted by new_global, refused by solver_new */
    {
        static const double indef[3] = {1.0, -1.0, 1.0}, sing[3] = {1.0, 0.0, 1.0};
        static const int64_t fcol[4] = {0, 2, 4, 5}, frow[5] = {0, 1, 0, 1, 2};
        static const double fval[5] = {1.0, 2.0, 2.0, 1.0, 1.0}; /* eigenvalues 3, -1, 1 */
        cadmm_csc H = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONE);
        const double *mats[2] = {indef, sing};
        const char *names[2] = {"M = diag(1, -1, 1)", "M = diag(1, 0, 1)"};
        for (int i = 0; i < 2; ++i) {
            cadmm_problem *bad = NULL;
            cadmm_csc M = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, mats[i]);
            REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, F3, W0, MU, &bad));
            solver_new_fails(names[i], "M", "not positive definite",
                             CADMM_ERR_NOT_POSITIVE_DEFINITE,
                             bad, s);
            cadmm_problem_free(bad);
        }
        {
            cadmm_problem *bad = NULL;
            cadmm_csc M = csc(3, 3, fcol, frow, fval);
            REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, F3, W0, MU, &bad));
            solver_new_fails("M coupled indefinite", "M", "not positive definite",
                             CADMM_ERR_NOT_POSITIVE_DEFINITE, bad, s);
            cadmm_problem_free(bad);
        }
    }
    /* local: W + rho I indefinite (symmetric W, given rho = 1) */
    {
        static const double wneg[3] = {-10.0, -20.0, -30.0};
        cadmm_problem *bad = NULL;
        cadmm_settings *s1 = valid_settings();
        cadmm_csc W = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, wneg);
        REQUIRE_OK(cadmm_settings_set_initial_rho(s1, "given", 1.0));
        REQUIRE_OK(cadmm_problem_new_local(1, &W, Q3, MU, &bad));
        solver_new_fails("W + rho I indefinite", "W", "not positive definite",
                         CADMM_ERR_NOT_POSITIVE_DEFINITE, bad, s1);
        cadmm_problem_free(bad);
        cadmm_settings_free(s1);
    }
    /* local: non-symmetric W with W + rho I singular (given rho = 1): LU fails */
    {
        /* W = [[-1, 1, 0], [0, -1, 0], [0, 0, -1]]: W + I = [[0, 1, 0], [0, 0, 0], [0, 0, 0]] */
        static const int64_t wc[4] = {0, 1, 3, 4}, wr[4] = {0, 0, 1, 2};
        static const double wv[4] = {-1.0, 1.0, -1.0, -1.0};
        cadmm_problem *bad = NULL;
        cadmm_settings *s1 = valid_settings();
        cadmm_csc W = csc(3, 3, wc, wr, wv);
        REQUIRE_OK(cadmm_settings_set_initial_rho(s1, "given", 1.0));
        REQUIRE_OK(cadmm_problem_new_local(1, &W, Q3, MU, &bad));
        solver_new_fails("non-symmetric W + rho I singular", "W", "singular", CADMM_ERR_SINGULAR,
                         bad, s1);
        cadmm_problem_free(bad);
        cadmm_settings_free(s1);
    }
    cadmm_settings_free(s);
    cadmm_problem_free(p);
}

static void test_solver_calls(void)
{
    cadmm_problem *p = valid_global();
    cadmm_settings *s = valid_settings();
    cadmm_solver *sv = NULL;
    cadmm_status st = -1;
    double r[3], u[3], v[3];
    cadmm_stats stats;
    cadmm_trace_point pt;
    size_t len;
    uint64_t cold_iterations = 0;

    REQUIRE_OK(cadmm_settings_set_trace(s, true));
    REQUIRE_OK(cadmm_settings_set_tolerance(s, 1e-10));
    REQUIRE_OK(cadmm_solver_new(p, s, &sv));
    REQUIRE(sv != NULL);
    CHECK(cadmm_solver_last_error(sv) != NULL && cadmm_solver_last_error(sv)[0] == '\0');

    /* before any solve: zeros, and setup statistics */
    for (int i = 0; i < 3; ++i) r[i] = u[i] = v[i] = SENTINEL_DOUBLE;
    EXPECT_RC(cadmm_solver_get_solution(sv, r, u, v), CADMM_OK);
    CHECK(r[0] == 0.0 && u[0] == 0.0 && v[0] == 0.0);
    memset(&stats, 0, sizeof stats);
    stats.struct_size = sizeof stats;
    EXPECT_RC(cadmm_solver_get_stats(sv, &stats), CADMM_OK);
    CHECK(stats.iterations == 0 && stats.status == CADMM_STATUS_UNSOLVED);
    CHECK(stats.struct_size == sizeof stats);
    CHECK(stats.rho > 0 && stats.refactorizations >= 1);
    CHECK(cadmm_solver_trace_len(sv) == 0);

    /* solve: NULL arguments */
    EXPECT_RC(cadmm_solver_solve(NULL, &st), CADMM_ERR_NULL_POINTER);
    CHECK(st == -1);
    prime_last_error();
    EXPECT_RC(cadmm_solver_solve(sv, NULL), CADMM_ERR_NULL_POINTER);
    check_message("solve(sv, NULL)", cadmm_solver_last_error(sv), 0, "status", "NULL");
    expect_last_error("solve(sv, NULL), thread message", "status", "NULL");

    EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
    CHECK_MSG(st == CADMM_STATUS_SOLVED, "status %d", st);
    EXPECT_RC(cadmm_solver_get_solution(sv, r, u, v), CADMM_OK);
    CHECK_MSG(fabs(r[0] - 2.0) < 1e-6 && fabs(r[1] + 0.2) < 1e-6 && fabs(r[2]) < 1e-6,
              "r = (%g, %g, %g), expected (2, -0.2, 0)", r[0], r[1], r[2]);
    CHECK(tu_norm(u, 3) < 1e-6 && tu_norm(v, 3) < 1e-6);
    EXPECT_RC(cadmm_solver_get_solution(sv, NULL, NULL, NULL), CADMM_OK);

    /* get_solution with a NULL solver writes nothing */
    {
        double rr[3] = {SENTINEL_DOUBLE, SENTINEL_DOUBLE, SENTINEL_DOUBLE};
        EXPECT_RC(cadmm_solver_get_solution(NULL, rr, NULL, NULL), CADMM_ERR_NULL_POINTER);
        CHECK(rr[0] == SENTINEL_DOUBLE && rr[2] == SENTINEL_DOUBLE);
    }

    /* stats */
    EXPECT_RC(cadmm_solver_get_stats(NULL, &stats), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_solver_get_stats(sv, NULL), CADMM_ERR_NULL_POINTER);
    memset(&stats, 0, sizeof stats);
    stats.struct_size = sizeof stats;
    EXPECT_RC(cadmm_solver_get_stats(sv, &stats), CADMM_OK);
    CHECK(stats.status == CADMM_STATUS_SOLVED && stats.iterations >= 1);
    CHECK(stats.error <= 1e-10 && stats.rho > 0 && stats.solve_seconds >= 0);
    CHECK(stats.refactorizations >= 1 && stats.setup_seconds >= 0);
    cold_iterations = stats.iterations;
    {
        /* struct_size too small: refused, nothing written */
        cadmm_stats small;
        memset(&small, 0xAB, sizeof small);
        small.struct_size = 0;
        EXPECT_RC(cadmm_solver_get_stats(sv, &small), CADMM_ERR_INVALID_VALUE);
        CHECK(small.struct_size == 0);
        {
            cadmm_stats ref;
            memset(&ref, 0xAB, sizeof ref);
            ref.struct_size = 0;
            CHECK_MSG(memcmp(&small, &ref, sizeof ref) == 0,
                      "get_stats wrote into a refused struct");
        }
        small.struct_size = offsetof(cadmm_stats, solve_seconds);
        EXPECT_RC(cadmm_solver_get_stats(sv, &small), CADMM_ERR_INVALID_VALUE);
        /* an older, shorter struct (up to solve_seconds): the appended fields stay untouched */
        memset(&small, 0xAB, sizeof small);
        small.struct_size = offsetof(cadmm_stats, anderson_accepted);
        EXPECT_RC(cadmm_solver_get_stats(sv, &small), CADMM_OK);
        CHECK(small.iterations == stats.iterations && small.status == stats.status);
        {
            uint64_t pattern;
            memset(&pattern, 0xAB, sizeof pattern);
            CHECK_MSG(small.anderson_accepted == pattern && small.anderson_rejected == pattern,
                      "get_stats wrote past struct_size");
        }
    }

    /* trace */
    len = cadmm_solver_trace_len(sv);
    CHECK_MSG(len >= 1 && len <= stats.iterations, "trace_len %zu for %llu iterations", len,
              (unsigned long long)stats.iterations);
    if (len >= 1) {
        cadmm_trace_point first, last;
        EXPECT_RC(cadmm_solver_get_trace(sv, 0, &first), CADMM_OK);
        EXPECT_RC(cadmm_solver_get_trace(sv, len - 1, &last), CADMM_OK);
        CHECK(first.iteration >= 1 && last.iteration >= first.iteration);
        CHECK(last.seconds >= first.seconds && first.rho > 0);
    }
    memset(&pt, 0, sizeof pt);
    pt.iteration = 4242;
    prime_last_error();
    EXPECT_RC(cadmm_solver_get_trace(sv, len, &pt), CADMM_ERR_INVALID_VALUE);
    /* the solver's message and the thread's: the index is out of range */
    check_message("get_trace(len)", cadmm_solver_last_error(sv), 0, "trace", "out of range");
    expect_last_error("get_trace(len), thread message", "trace", "out of range");
    CHECK_MSG(strcmp(cadmm_last_error(), cadmm_solver_last_error(sv)) == 0,
              "thread message \"%s\" differs from the solver's \"%s\"", cadmm_last_error(),
              cadmm_solver_last_error(sv));
    EXPECT_RC(cadmm_solver_get_trace(sv, (size_t)-1, &pt), CADMM_ERR_INVALID_VALUE);
    CHECK(pt.iteration == 4242);
    prime_last_error();
    EXPECT_RC(cadmm_solver_get_trace(NULL, 0, &pt), CADMM_ERR_NULL_POINTER);
    expect_last_error("get_trace(NULL, ...)", "sv", "NULL");
    EXPECT_RC(cadmm_solver_get_trace(sv, 0, NULL), CADMM_ERR_NULL_POINTER);
    CHECK(pt.iteration == 4242);
    /* the solver keeps the message of its own last failure */
    check_message("get_trace(sv, 0, NULL)", cadmm_solver_last_error(sv), 0, "out", "NULL");

    /* warm start */
    {
        double rn[3] = {2.0, NAN, 0.0}, vi[3] = {0.0, INFINITY, 0.0};
        EXPECT_RC(cadmm_solver_warm_start(NULL, r, v), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_warm_start(sv, NULL, v), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_warm_start(sv, rn, v), CADMM_ERR_INVALID_VALUE);
        EXPECT_RC(cadmm_solver_warm_start(sv, r, vi), CADMM_ERR_INVALID_VALUE);
        /* from the solution itself: solved again, no more iterations than cold */
        EXPECT_RC(cadmm_solver_warm_start(sv, r, v), CADMM_OK);
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        stats.struct_size = sizeof stats;
        EXPECT_RC(cadmm_solver_get_stats(sv, &stats), CADMM_OK);
        CHECK_MSG(stats.iterations <= cold_iterations,
                  "warm start from the solution took %llu iterations, cold %llu",
                  (unsigned long long)stats.iterations, (unsigned long long)cold_iterations);
        /* r only (v NULL) */
        EXPECT_RC(cadmm_solver_warm_start(sv, r, NULL), CADMM_OK);
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
    }

    /* update */
    {
        static const double f2[3] = {-4.0, 0.4, 0.0};
        static const double mind[3] = {2.0, -1.0, 2.0};
        static const double w6[6] = {0}, mu2[2] = {0.5, 0.5};
        static const int64_t hc[4] = {0, 2, 3, 4}, hr[4] = {0, 1, 1, 2};
        static const double hv[4] = {1.0, 0.5, 1.0, 1.0};
        static const int64_t h6c[7] = {0, 1, 2, 3, 4, 5, 6}, h6r[6] = {0, 1, 2, 0, 1, 2};
        static const double h6v[6] = {1, 1, 1, 1, 1, 1};
        cadmm_csc M = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, TWO);
        cadmm_csc H = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONE);
        cadmm_csc Hpat = csc(3, 3, hc, hr, hv);
        cadmm_csc H6 = csc(3, 6, h6c, h6r, h6v);
        cadmm_csc Mind = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, mind);
        cadmm_problem *p2 = NULL, *pdim = NULL, *ppat = NULL, *pind = NULL, *ploc = valid_local();
        REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, f2, W0, MU, &p2));
        REQUIRE_OK(cadmm_problem_new_global(3, 2, &M, &H6, F3, w6, mu2, &pdim));
        REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &Hpat, F3, W0, MU, &ppat));
        REQUIRE_OK(cadmm_problem_new_global(3, 1, &Mind, &H, F3, W0, MU, &pind));

        EXPECT_RC(cadmm_solver_update(NULL, p2), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_update(sv, NULL), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_update(sv, pdim), CADMM_ERR_DIMENSION);
        /* the other form is refused before any size is compared */
        EXPECT_RC(cadmm_solver_update(sv, ploc), CADMM_ERR_UNSUPPORTED);
        EXPECT_RC(cadmm_solver_update(sv, ppat), CADMM_ERR_PATTERN_CHANGED);
        /* a refused update changes nothing: the solver solves the problem it held, f = F3 on
           M = 2 I, which sticks: r = -F3 */
        st = -1;
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, u, v), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 2.0) < 1e-6 && fabs(r[1] + 0.2) < 1e-6 && fabs(r[2]) < 1e-6,
                  "after refused updates r = (%g, %g, %g), expected (2, -0.2, 0)", r[0], r[1],
                  r[2]);
        EXPECT_RC(cadmm_solver_warm_start(sv, r, v), CADMM_OK);
        /* also when M does not factorize, which is found only once the values are taken */
        EXPECT_RC(cadmm_solver_update(sv, pind), CADMM_ERR_NOT_POSITIVE_DEFINITE);
        check_message("update with M indefinite", cadmm_solver_last_error(sv), 0, "M",
                      "not positive definite");
        st = -1;
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, NULL), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 2.0) < 1e-6 && fabs(r[1] + 0.2) < 1e-6 && fabs(r[2]) < 1e-6,
                  "after a refused indefinite M r = (%g, %g, %g), expected (2, -0.2, 0)", r[0],
                  r[1], r[2]);
        /* then a good update: f doubled, so r doubles */
        EXPECT_RC(cadmm_solver_update(sv, p2), CADMM_OK);
        st = -1;
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, NULL), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 4.0) < 1e-6 && fabs(r[1] + 0.4) < 1e-6 && fabs(r[2]) < 1e-6,
                  "after update r = (%g, %g, %g), expected (4, -0.4, 0)", r[0], r[1], r[2]);
        cadmm_problem_free(p2);
        cadmm_problem_free(pdim);
        cadmm_problem_free(ppat);
        cadmm_problem_free(pind);
        cadmm_problem_free(ploc);
    }
    cadmm_solver_free(sv);

    /* the problem and settings may be freed while the solver lives (it copies them) */
    {
        cadmm_problem *pl = valid_local();
        cadmm_settings *s2 = valid_settings();
        cadmm_solver *sl = NULL;
        REQUIRE_OK(cadmm_solver_new(pl, s2, &sl));
        cadmm_problem_free(pl);
        cadmm_settings_free(s2);
        st = -1;
        EXPECT_RC(cadmm_solver_solve(sl, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        v[0] = v[1] = v[2] = SENTINEL_DOUBLE;
        EXPECT_RC(cadmm_solver_get_solution(sl, r, u, v), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 2.0) < 1e-6 && fabs(r[1] + 0.2) < 1e-6,
                  "local r = (%g, %g, %g)", r[0], r[1], r[2]);
        /* for a local problem v is ignored (left untouched) */
        CHECK(v[0] == SENTINEL_DOUBLE && v[2] == SENTINEL_DOUBLE);
        cadmm_solver_free(sl);
    }
    /* a limit reached is a status, not a failure */
    {
        cadmm_settings *s1 = valid_settings();
        cadmm_solver *s_lim = NULL;
        REQUIRE_OK(cadmm_settings_set_max_iterations(s1, 1));
        REQUIRE_OK(cadmm_settings_set_tolerance(s1, 1e-14));
        REQUIRE_OK(cadmm_solver_new(p, s1, &s_lim));
        EXPECT_RC(cadmm_solver_solve(s_lim, &st), CADMM_OK);
        CHECK_MSG(st == CADMM_STATUS_MAX_ITERATIONS, "status %d with max_iterations = 1", st);
        cadmm_solver_free(s_lim);
        cadmm_settings_free(s1);
    }
    cadmm_settings_free(s);
    cadmm_problem_free(p);
}

/* ---- FCLib I/O ------------------------------------------------------------------------------ */

/* Returns 1 when the part that needs the data directory could not run (it is missing). */
/* cadmm_solver_rebuild: a problem of other sizes and pattern replaces the solver's, with and
 * without a time limit (with one, the sweeps are built in the memory of those they replace);
 * a refused problem changes nothing. M = 2 I, f = F3: a contact under the identity sticks
 * with r = -F3 and v = 0; two contacts on the same rows stick with r_a + r_b = -F3. */
static void test_solver_rebuild(void)
{
    static const double f2[3] = {-4.0, 0.4, 0.0}, mind[3] = {2.0, -1.0, 2.0};
    static const double w6[6] = {0}, mu2[2] = {0.5, 0.5};
    static const int64_t h6c[7] = {0, 1, 2, 3, 4, 5, 6}, h6r[6] = {0, 1, 2, 0, 1, 2};
    static const double h6v[6] = {1, 1, 1, 1, 1, 1};
    cadmm_csc M = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, TWO);
    cadmm_csc H = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, ONE);
    cadmm_csc H6 = csc(3, 6, h6c, h6r, h6v);
    cadmm_csc Mind = csc(3, 3, DIAG_COLPTR, DIAG_ROWIND, mind);
    cadmm_problem *one = NULL, *two = NULL, *doubled = NULL, *indefinite = NULL;
    REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, F3, W0, MU, &one));
    REQUIRE_OK(cadmm_problem_new_global(3, 2, &M, &H6, F3, w6, mu2, &two));
    REQUIRE_OK(cadmm_problem_new_global(3, 1, &M, &H, f2, W0, MU, &doubled));
    REQUIRE_OK(cadmm_problem_new_global(3, 1, &Mind, &H, F3, W0, MU, &indefinite));
    for (int budgeted = 0; budgeted < 2; budgeted++) {
        cadmm_settings *s = valid_settings();
        cadmm_solver *sv = NULL;
        cadmm_status st = -1;
        double r[6], v[3];
        if (budgeted) REQUIRE_OK(cadmm_settings_set_time_limit(s, 10.0));
        REQUIRE_OK(cadmm_solver_new(one, s, &sv));
        EXPECT_RC(cadmm_solver_rebuild(NULL, two), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_rebuild(sv, NULL), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_solver_rebuild(sv, indefinite), CADMM_ERR_NOT_POSITIVE_DEFINITE);
        check_message("rebuild with M indefinite", cadmm_solver_last_error(sv), 0, "M",
                      "not positive definite");
        /* refused: still the first problem */
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, NULL), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 2.0) < 1e-6 && fabs(r[1] + 0.2) < 1e-6 && fabs(r[2]) < 1e-6,
                  "budgeted %d: after a refused rebuild r = (%g, %g, %g), expected (2, -0.2, 0)",
                  budgeted, r[0], r[1], r[2]);
        /* two contacts: six impulses */
        EXPECT_RC(cadmm_solver_rebuild(sv, two), CADMM_OK);
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, v), CADMM_OK);
        CHECK_MSG(fabs(r[0] + r[3] - 2.0) < 1e-6 && fabs(r[1] + r[4] + 0.2) < 1e-6 &&
                      fabs(r[2] + r[5]) < 1e-6 && fabs(v[0]) + fabs(v[1]) + fabs(v[2]) < 1e-6,
                  "budgeted %d: two contacts r = (%g, %g, %g) + (%g, %g, %g), v = (%g, %g, %g)",
                  budgeted, r[0], r[1], r[2], r[3], r[4], r[5], v[0], v[1], v[2]);
        /* back to one contact, f doubled: r doubles */
        EXPECT_RC(cadmm_solver_rebuild(sv, doubled), CADMM_OK);
        EXPECT_RC(cadmm_solver_solve(sv, &st), CADMM_OK);
        CHECK(st == CADMM_STATUS_SOLVED);
        EXPECT_RC(cadmm_solver_get_solution(sv, r, NULL, NULL), CADMM_OK);
        CHECK_MSG(fabs(r[0] - 4.0) < 1e-6 && fabs(r[1] + 0.4) < 1e-6 && fabs(r[2]) < 1e-6,
                  "budgeted %d: after rebuilds r = (%g, %g, %g), expected (4, -0.4, 0)",
                  budgeted, r[0], r[1], r[2]);
        /* and the same pattern updates as before */
        EXPECT_RC(cadmm_solver_update(sv, one), CADMM_OK);
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
    }
    cadmm_problem_free(one);
    cadmm_problem_free(two);
    cadmm_problem_free(doubled);
    cadmm_problem_free(indefinite);
}

static int test_fclib(const char *data_dir)
{
    cadmm_problem *p = SENTINEL_PROBLEM;
    const cadmm_result no_file = CADMM_TEST_HAVE_FCLIB ? CADMM_ERR_IO : CADMM_ERR_UNSUPPORTED;
    char path[4096];

    EXPECT_RC(cadmm_problem_read_fclib(NULL, &p), CADMM_ERR_NULL_POINTER);
    EXPECT_RC(cadmm_problem_read_fclib("x.hdf5", NULL), CADMM_ERR_NULL_POINTER);
    prime_last_error();
    EXPECT_RC(cadmm_problem_read_fclib("/nonexistent/dir/missing.hdf5", &p), no_file);
    expect_last_error("read_fclib of a missing file", NULL, "/nonexistent/dir/missing.hdf5");
    EXPECT_RC(cadmm_problem_read_fclib("", &p), no_file);
    EXPECT_RC(cadmm_problem_read_fclib(".", &p), no_file); /* a directory */
    {
        /* a file that is not HDF5 */
        FILE *fp = fopen("test_api_errors_not_hdf5.txt", "w");
        REQUIRE(fp != NULL);
        fputs("not an HDF5 file\n", fp);
        fclose(fp);
        EXPECT_RC(cadmm_problem_read_fclib("test_api_errors_not_hdf5.txt", &p), no_file);
        remove("test_api_errors_not_hdf5.txt");
    }
    CHECK_MSG(p == SENTINEL_PROBLEM, "read_fclib wrote *out on failure");

    {
        cadmm_problem *g = valid_global();
        EXPECT_RC(cadmm_problem_write_fclib(NULL, "x.h5"), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_problem_write_fclib(g, NULL), CADMM_ERR_NULL_POINTER);
        EXPECT_RC(cadmm_problem_write_fclib(g, "/nonexistent/dir/out.h5"), no_file);
        if (CADMM_TEST_HAVE_FCLIB) {
            /* round trip, global and local: same sizes, same error at a candidate */
            cadmm_problem *l = valid_local();
            cadmm_problem *orig[2] = {g, l};
            const char *files[2] = {"test_api_errors_global.h5", "test_api_errors_local.h5"};
            const double r[3] = {1.5, -0.1, 0.3}, v[3] = {0.1, 0.2, -0.3};
            for (int i = 0; i < 2; ++i) {
                cadmm_problem *back = NULL;
                double e1 = -1, e2 = -2;
                size_t n1, n2, c1, c2;
                bool g1, g2;
                EXPECT_RC(cadmm_problem_write_fclib(orig[i], files[i]), CADMM_OK);
                EXPECT_RC(cadmm_problem_read_fclib(files[i], &back), CADMM_OK);
                if (back == NULL) continue;
                REQUIRE_OK(cadmm_problem_dims(orig[i], &n1, &c1, &g1));
                REQUIRE_OK(cadmm_problem_dims(back, &n2, &c2, &g2));
                CHECK(n1 == n2 && c1 == c2 && g1 == g2);
                REQUIRE_OK(cadmm_problem_error(orig[i], r, NULL, v, &e1));
                REQUIRE_OK(cadmm_problem_error(back, r, NULL, v, &e2));
                CHECK_MSG(e1 == e2, "round trip %s: error %.17g vs %.17g", files[i], e1, e2);
                cadmm_problem_free(back);
                remove(files[i]);
            }
            cadmm_problem_free(l);
        }
        cadmm_problem_free(g);
    }

    if (!tu_is_dir(data_dir)) {
        printf("SKIP (FCLib part): data directory '%s' not found\n", data_dir);
        return 1;
    }
    if (!CADMM_TEST_HAVE_FCLIB) {
        /* A build without FCLib I/O refuses an existing, valid file, and says why. */
        cadmm_problem *q = SENTINEL_PROBLEM;
        tu_join(path, sizeof path, data_dir, "local/FrictionContact3D_1c.hdf5");
        if (!tu_is_file(path)) {
            TU_FAIL("%s is missing from the data directory", path);
            return 0;
        }
        prime_last_error();
        EXPECT_RC(cadmm_problem_read_fclib(path, &q), CADMM_ERR_UNSUPPORTED);
        /* (not the word "fclib": the path has it) */
        expect_last_error("read_fclib without the fclib feature", NULL, "support|feature");
        CHECK_MSG(q == SENTINEL_PROBLEM, "read_fclib wrote *out on failure");
        printf("library built without the fclib feature: read_fclib refuses %s\n", path);
        return 0;
    }
    {
        static const struct {
            const char *file;
            size_t n, nc;
            bool global;
        } known[] = {
            {"global/GFC3D_Example1.hdf5", 3, 1, true},
            {"global/GFC3D_OneContact.hdf5", 39, 1, true},
            {"global/Box_Stacks-i0122-82-5.hdf5", 450, 82, true},
            {"local/FrictionContact3D_1c.hdf5", 0, 1, false},
            {"local/LMGC_100_PR_PerioBox-i00361-60-03000.hdf5", 0, 60, false},
        };
        for (size_t i = 0; i < sizeof known / sizeof known[0]; ++i) {
            cadmm_problem *q = NULL;
            size_t n = 0, nc = 0;
            bool g = false;
            tu_join(path, sizeof path, data_dir, known[i].file);
            if (!tu_is_file(path)) {
                TU_FAIL("%s is missing from the data directory", path);
                continue;
            }
            EXPECT_RC(cadmm_problem_read_fclib(path, &q), CADMM_OK);
            if (q == NULL) continue;
            EXPECT_RC(cadmm_problem_dims(q, &n, &nc, &g), CADMM_OK);
            CHECK_MSG(n == known[i].n && nc == known[i].nc && g == known[i].global,
                      "%s: dims (%zu, %zu, %d)", known[i].file, n, nc, (int)g);
            cadmm_problem_free(q);
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    const char *data_dir = argc > 1 ? argv[1] : "../shared/data/fclib";
    int skipped, rc;
    printf("cadmm %s: API error tests (data: %s)\n", cadmm_version(), data_dir);
    test_basics();
    test_global_inputs();
    test_local_inputs();
    test_problem_queries();
    test_joints();
    test_settings();
    test_solver_new_failures();
    test_solver_calls();
    test_solver_rebuild();
    skipped = test_fclib(data_dir);
    cadmm_problem_free(primer_problem);
    rc = tu_finish("test_api_errors");
    if (rc == 0 && skipped) {
        /* every other check passed, but part of the test did not run: report a skip */
        printf("test_api_errors: SKIPPED in part (no FCLib data directory '%s')\n", data_dir);
        return TU_SKIP;
    }
    return rc;
}
