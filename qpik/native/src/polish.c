/* The exact QP answer from an ADMM iterate's active-set guess: qpik.control.solvers.osqp.polish in C.
 *
 * The same steps as the numpy version (its docstring has the math): P = L L^T, x0 = -P^-1 c,
 * H = Abar P^-1 Abar^T, of which only the columns of the rows that are ever in W are computed (when a row
 * first enters: the guess, then each row a dual step adds; H's other entries are never read); the guessed rows (OSQP's rule on z + y), reduced to independent ones by a
 * pivoted Cholesky of H_WW scaled to unit diagonal; negative multipliers dropped; then Goldfarb-Idnani
 * dual active-set steps while a bound is violated; the answer checked (every bound within tol, every
 * multiplier >= -tol, both scaled by 1 + max|c| + the largest finite bound). Returns None where the numpy
 * version does. Module qpik_polish, built at first use by qpik.fastcall.build.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Cholesky P = L L^T in place (lower triangle of the row-major n x n L); 0 if P is not positive definite. */
static int cholesky(double *L, int n) {
    for (int j = 0; j < n; ++j) {
        double d = L[j * n + j];
        for (int k = 0; k < j; ++k) d -= L[j * n + k] * L[j * n + k];
        if (!(d > 0.0)) return 0;
        d = sqrt(d);
        L[j * n + j] = d;
        for (int i = j + 1; i < n; ++i) {
            double s = L[i * n + j];
            for (int k = 0; k < j; ++k) s -= L[i * n + k] * L[j * n + k];
            L[i * n + j] = s / d;
        }
    }
    return 1;
}

/* x <- P^-1 x with P = L L^T. */
static void chol_solve(const double *L, int n, double *x) {
    for (int i = 0; i < n; ++i) {
        double s = x[i];
        for (int k = 0; k < i; ++k) s -= L[i * n + k] * x[k];
        x[i] = s / L[i * n + i];
    }
    for (int i = n - 1; i >= 0; --i) {
        double s = x[i];
        for (int k = i + 1; k < n; ++k) s -= L[k * n + i] * x[k];
        x[i] = s / L[i * n + i];
    }
}

/* Entry (i, j) of the (M, M) matrix H stored column by column (column j contiguous). */
#define HC(i, j) H[(size_t)(j) * M + (i)]

/* Solve H[W, W] sol = rhs (k = |W|) by LU with partial pivoting; 0 if a pivot is exactly zero. */
static int solve_w(const double *H, int M, const int *W, int k, const double *rhs, double *sol, double *G) {
    for (int i = 0; i < k; ++i) {
        for (int j = 0; j < k; ++j) G[i * k + j] = HC(W[i], W[j]);
        sol[i] = rhs[i];
    }
    for (int c = 0; c < k; ++c) {
        int p = c;
        for (int i = c + 1; i < k; ++i)
            if (fabs(G[i * k + c]) > fabs(G[p * k + c])) p = i;
        if (G[p * k + c] == 0.0) return 0;
        if (p != c) {
            for (int j = 0; j < k; ++j) {
                double t = G[c * k + j];
                G[c * k + j] = G[p * k + j], G[p * k + j] = t;
            }
            double t = sol[c];
            sol[c] = sol[p], sol[p] = t;
        }
        for (int i = c + 1; i < k; ++i) {
            double f = G[i * k + c] / G[c * k + c];
            if (f == 0.0) continue;
            for (int j = c; j < k; ++j) G[i * k + j] -= f * G[c * k + j];
            sol[i] -= f * sol[c];
        }
    }
    for (int i = k - 1; i >= 0; --i) {
        double s = sol[i];
        for (int j = i + 1; j < k; ++j) s -= G[i * k + j] * sol[j];
        sol[i] = s / G[i * k + i];
    }
    return 1;
}

static int ascending_int(const void *a, const void *b) { return *(const int *)a - *(const int *)b; }

/* The rows of W (k of them) that are linearly independent: pivoted Cholesky of H[W, W] scaled to unit
 * diagonal, stopping at a pivot <= 1e-12 (LAPACK dpstrf's rule); the kept rows sorted. Returns their count. */
static int independent(const double *H, int M, int *W, int k, double *G) {
    if (k <= 1) return k;
    int *perm = malloc(sizeof(int) * (size_t)k);
    if (!perm) return -1;
    for (int i = 0; i < k; ++i) {
        perm[i] = i;
        for (int j = 0; j < k; ++j)
            G[i * k + j] = HC(W[i], W[j]) / sqrt(HC(W[i], W[i]) * HC(W[j], W[j]));
    }
    int rank = 0;
    for (; rank < k; ++rank) { /* G holds the Schur complement in rows/columns rank..k-1 (permuted) */
        int p = rank;
        for (int i = rank + 1; i < k; ++i)
            if (G[perm[i] * k + perm[i]] > G[perm[p] * k + perm[p]]) p = i;
        double d = G[perm[p] * k + perm[p]];
        if (!(d > 1e-12)) break;
        int t = perm[rank];
        perm[rank] = perm[p], perm[p] = t;
        int r = perm[rank];
        double s = sqrt(d);
        for (int i = rank + 1; i < k; ++i) G[perm[i] * k + r] /= s;
        for (int i = rank + 1; i < k; ++i)
            for (int j = rank + 1; j < k; ++j) G[perm[i] * k + perm[j]] -= G[perm[i] * k + r] * G[perm[j] * k + r];
    }
    if (rank < k) {
        qsort(perm, (size_t)rank, sizeof(int), ascending_int);
        int *kept = malloc(sizeof(int) * (size_t)rank);
        if (!kept) {
            free(perm);
            return -1;
        }
        for (int i = 0; i < rank; ++i) kept[i] = W[perm[i]];
        memcpy(W, kept, sizeof(int) * (size_t)rank);
        free(kept);
    }
    free(perm);
    return rank;
}

#define ABAR(i, j) Abar[(size_t)(i) * n + (j)] /* Abar (M, n) row-major */

/* Column j of H, H[i, j] = Abar_i . C_j with C_j = P^-1 Abar_j (row j of C, (M, n)), 0 where row i or j is not
 * live; computed on first use (known[j]). */
static void column(int n, int M, const double *Abar, const double *L, const unsigned char *live,
                   unsigned char *known, double *C, double *H, int j) {
    if (known[j]) return;
    known[j] = 1;
    double *Cj = C + (size_t)j * n;
    if (!live[j]) {
        for (int i = 0; i < M; ++i) HC(i, j) = 0.0;
        return;
    }
    for (int t = 0; t < n; ++t) Cj[t] = ABAR(j, t);
    chol_solve(L, n, Cj);
    for (int i = 0; i < M; ++i) {
        double s = 0.0;
        if (live[i])
            for (int t = 0; t < n; ++t) s += ABAR(i, t) * Cj[t];
        HC(i, j) = s;
    }
}

/* The polish; 1 with the answer in out, 0 for no answer, -1 out of memory. */

static int polish(int n, int M, const double *P, const double *c, const double *Abar, const double *lo,
                  const double *hi, const double *x, const double *y, double tol, int max_steps, double *out) {
    size_t V = (size_t)M + 1; /* room of each vector over the rows (W holds at most M + 1) */
    size_t need = (size_t)n * n + 2 * (size_t)n + (size_t)n * M + (size_t)M * M + 7 * V + V * V;
    double *L = malloc(sizeof(double) * need);
    int *W = malloc(sizeof(int) * 2 * ((size_t)M + 1));
    unsigned char *lower = malloc(3 * ((size_t)M + 1)), *live = lower + M + 1; /* live: a finite bound */
    unsigned char *known = live + M + 1; /* known[j]: column j of H (and row j of C) computed */
    if (!L || !W || !lower) {
        free(L), free(W), free(lower);
        return -1;
    }
    double *x0 = L + n * n, *xs = x0 + n, *C = xs + n, *H = C + (size_t)n * M, *r0 = H + (size_t)M * M;
    double *b = r0 + V, *z = b + V, *nu = z + V, *g = nu + V, *dz = g + V, *rhs = dz + V, *G = rhs + V;
    int *guess = W + M + 1, status = 0;
    int k = 0, ng = 0, steps = 0;
    double *sigma = NULL;

    for (int i = 0; i < M; ++i) { /* the guess: z + y below lo or above hi */
        double w = y[i];
        for (int j = 0; j < n; ++j) w += ABAR(i, j) * x[j];
        lower[i] = w < lo[i];
        if (lower[i] || w > hi[i]) guess[ng++] = i;
    }
    memcpy(L, P, sizeof(double) * (size_t)n * n);
    if (!cholesky(L, n)) goto done;
    for (int j = 0; j < n; ++j) x0[j] = -c[j];
    chol_solve(L, n, x0);
    double viol = -INFINITY, bound = 0.0, cmax = 0.0;
    for (int i = 0; i < M; ++i) {
        double r = 0.0;
        for (int j = 0; j < n; ++j) r += ABAR(i, j) * x0[j];
        r0[i] = r;
        viol = fmax(viol, fmax(lo[i] - r, r - hi[i]));
        if (isfinite(lo[i])) bound = fmax(bound, fabs(lo[i]));
        if (isfinite(hi[i])) bound = fmax(bound, fabs(hi[i]));
    }
    if (viol <= 0.0 && ng == 0) { /* nothing active, every bound met strictly */
        memcpy(out, x0, sizeof(double) * (size_t)n);
        status = 1;
        goto done;
    }
    for (int j = 0; j < n; ++j) cmax = fmax(cmax, fabs(c[j]));
    double scale = tol * (1.0 + cmax + bound);
    if (ng == 0 && viol <= scale) {
        memcpy(out, x0, sizeof(double) * (size_t)n);
        status = 1;
        goto done;
    }
    /* A row bounded by +-inf on both sides (a damper beyond its influence distance) can be neither violated nor
       active: its part of H stays 0. */
    for (int i = 0; i < M; ++i) live[i] = isfinite(lo[i]) || isfinite(hi[i]), known[i] = 0;
    for (int i = 0; i < ng; ++i) column(n, M, Abar, L, live, known, C, H, guess[i]);
    for (int i = 0; i < M; ++i) b[i] = lower[i] ? lo[i] : hi[i];
    memcpy(W, guess, sizeof(int) * (size_t)ng);
    k = independent(H, M, W, ng, G);
    if (k < 0) {
        status = -1;
        goto done;
    }
    sigma = malloc(sizeof(double) * ((size_t)M + 1));
    if (!sigma) {
        status = -1;
        goto done;
    }
    for (int i = 0; i < k; ++i) sigma[i] = lower[W[i]] ? 1.0 : -1.0;
    for (;;) { /* a dual feasible start: drop the most negative multiplier until none is */
        for (int i = 0; i < k; ++i) rhs[i] = b[W[i]] - r0[W[i]];
        if (!solve_w(H, M, W, k, rhs, nu, G)) goto done;
        int worst = -1;
        for (int i = 0; i < k; ++i)
            if (sigma[i] * nu[i] < 0.0 && (worst < 0 || sigma[i] * nu[i] < sigma[worst] * nu[worst])) worst = i;
        if (worst < 0) break;
        for (int i = worst; i + 1 < k; ++i) W[i] = W[i + 1], sigma[i] = sigma[i + 1];
        --k;
    }
    for (int i = 0; i < M; ++i) {
        double s = r0[i];
        for (int t = 0; t < k; ++t) s += HC(i, W[t]) * nu[t];
        z[i] = s;
    }
    for (;;) {
        int p = 0;
        double vp = -INFINITY;
        for (int i = 0; i < M; ++i) {
            double v = fmax(lo[i] - z[i], z[i] - hi[i]);
            if (v > vp) vp = v, p = i;
        }
        if (vp <= scale) break;
        column(n, M, Abar, L, live, known, C, H, p);
        double sp = lo[p] - z[p] > 0.0 ? 1.0 : -1.0;
        b[p] = sp > 0.0 ? lo[p] : hi[p];
        double gap = vp, nu_p = 0.0;
        for (;;) { /* raise p's multiplier until p is met (it joins W) or a constraint of W leaves */
            if (++steps > max_steps) goto done;
            if (k) {
                for (int i = 0; i < k; ++i) rhs[i] = HC(W[i], p);
                if (!solve_w(H, M, W, k, rhs, g, G)) goto done;
                for (int i = 0; i < k; ++i) g[i] = -g[i];
            }
            for (int i = 0; i < M; ++i) {
                double s = HC(i, p);
                for (int t = 0; t < k; ++t) s += HC(i, W[t]) * g[t];
                dz[i] = sp * s;
            }
            double rate = sp * dz[p];
            double full = rate > 1e-10 * HC(p, p) ? gap / rate : INFINITY;
            int j = -1;
            double ratio = INFINITY;
            for (int i = 0; i < k; ++i) {
                double u = sigma[i] * sp * g[i];
                if (u < 0.0) {
                    double r = sigma[i] * nu[i] / -u;
                    if (j < 0 || r < ratio) ratio = r, j = i;
                }
            }
            double t = j >= 0 ? fmin(full, ratio) : full;
            if (!isfinite(t)) goto done; /* p cannot be met with W's constraints: infeasible */
            for (int i = 0; i < M; ++i) z[i] += t * dz[i];
            gap -= t * rate;
            for (int i = 0; i < k; ++i) nu[i] += t * sp * g[i];
            nu_p += sp * t;
            if (t == full) {
                W[k] = p, sigma[k] = sp, nu[k] = nu_p, ++k;
                break;
            }
            for (int i = j; i + 1 < k; ++i) W[i] = W[i + 1], sigma[i] = sigma[i + 1], nu[i] = nu[i + 1];
            --k;
        }
    }
    if (steps) { /* re-solve on the final W: the answer is not left with the steps' rounding */
        for (int i = 0; i < k; ++i) rhs[i] = b[W[i]] - r0[W[i]];
        if (!solve_w(H, M, W, k, rhs, nu, G)) goto done;
    }
    for (int i = 0; i < k; ++i)
        if (sigma[i] * nu[i] < -scale) goto done;
    for (int j = 0; j < n; ++j) {
        double s = x0[j];
        for (int t = 0; t < k; ++t) s += C[(size_t)W[t] * n + j] * nu[t];
        xs[j] = s;
    }
    for (int i = 0; i < M; ++i) {
        double s = 0.0;
        for (int j = 0; j < n; ++j) s += ABAR(i, j) * xs[j];
        if (fmax(lo[i] - s, s - hi[i]) > scale) goto done;
    }
    memcpy(out, xs, sizeof(double) * (size_t)n);
    status = 1;
done:
    free(L), free(W), free(lower), free(sigma);
    return status;
}

/* a as a float64 C-contiguous array (a new reference: itself where it is one) of `size` entries (any if < 0), or
 * NULL with an error naming it. */
static PyArrayObject *array_of(PyObject *a, npy_intp size, const char *name) {
    PyArrayObject *arr = (PyArrayObject *)a;
    if (PyArray_CheckExact(a) && PyArray_TYPE(arr) == NPY_DOUBLE && PyArray_ISCARRAY_RO(arr) && PyArray_ISNOTSWAPPED(arr))
        Py_INCREF(a); /* the common case, without numpy's conversion machinery */
    else
        arr = (PyArrayObject *)PyArray_FROM_OTF(a, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY);
    if (arr && size >= 0 && PyArray_SIZE(arr) != size) {
        PyErr_Format(PyExc_ValueError, "polish: %s must have %zd entries, got %zd", name, (Py_ssize_t)size,
                     (Py_ssize_t)PyArray_SIZE(arr));
        Py_CLEAR(arr);
    }
    return arr;
}

/* polish(P (n, n), c (n,), A (m, n), lb (n,), ub (n,), l (m,), u (m,), x (n,), y (n + m,), tol, max_steps)
 * -> x (n,) or None: the QP with the box lb <= x <= ub and the rows l <= A x <= u, as Abar = [I; A],
 * lo = [lb; l], hi = [ub; u] (M = n + m rows; y the multipliers of those rows). */
static PyObject *py_polish(PyObject *mod, PyObject *const *args, Py_ssize_t nargs) {
    static const char *names[] = {"P", "c", "A", "lb", "ub", "l", "u", "x", "y"};
    if (nargs != 11) {
        PyErr_SetString(PyExc_TypeError, "polish takes 11 arguments");
        return NULL;
    }
    double tol = PyFloat_AsDouble(args[9]);
    long steps = PyLong_AsLong(args[10]);
    if (PyErr_Occurred()) return NULL;
    PyArrayObject *arr[9] = {NULL};
    PyObject *out = NULL;
    double *Abar = NULL;
    npy_intp n = 0, m = 0; /* c's size and l's, then every array's checked against them */
    if (!(arr[1] = array_of(args[1], -1, "c")) || !(arr[5] = array_of(args[5], -1, "l"))) goto fail;
    n = PyArray_SIZE(arr[1]), m = PyArray_SIZE(arr[5]);
    npy_intp M = n + m, sizes[9] = {n * n, n, m * n, n, n, m, m, n, M};
    for (int k = 0; k < 9; ++k)
        if (!arr[k] && !(arr[k] = array_of(args[k], sizes[k], names[k]))) goto fail;
    const double *d[9];
    for (int k = 0; k < 9; ++k) d[k] = (const double *)PyArray_DATA(arr[k]);
    Abar = malloc(sizeof(double) * (size_t)(M * n + 2 * M)); /* Abar (M, n) row-major, then lo, hi */
    if (!Abar) {
        PyErr_NoMemory();
        goto fail;
    }
    double *lo = Abar + M * n, *hi = lo + M;
    for (npy_intp i = 0; i < n; ++i)
        for (npy_intp j = 0; j < n; ++j) Abar[i * n + j] = i == j ? 1.0 : 0.0;
    memcpy(Abar + n * n, d[2], sizeof(double) * (size_t)(m * n));
    memcpy(lo, d[3], sizeof(double) * (size_t)n), memcpy(lo + n, d[5], sizeof(double) * (size_t)m);
    memcpy(hi, d[4], sizeof(double) * (size_t)n), memcpy(hi + n, d[6], sizeof(double) * (size_t)m);
    out = PyArray_SimpleNew(1, &n, NPY_DOUBLE);
    if (!out) goto fail;
    int status = polish((int)n, (int)M, d[0], d[1], Abar, lo, hi, d[7], d[8], tol, (int)steps,
                        PyArray_DATA((PyArrayObject *)out));
    if (status != 1) {
        Py_CLEAR(out);
        if (status < 0) PyErr_NoMemory();
        else Py_INCREF(Py_None), out = Py_None;
    }
fail:
    free(Abar);
    for (int k = 0; k < 9; ++k) Py_XDECREF(arr[k]);
    return out;
}

static PyMethodDef methods[] = {
    {"polish", (PyCFunction)(void (*)(void))py_polish, METH_FASTCALL,
     "polish(P, c, A, lb, ub, l, u, x, y, tol, max_steps): the exact QP answer, or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "qpik_polish", NULL, -1, methods};

PyMODINIT_FUNC PyInit_qpik_polish(void) {
    import_array();
    return PyModule_Create(&module);
}
