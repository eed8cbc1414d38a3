/* Real roots of F(delta) = A(cos delta) + sin delta B(cos delta) (qpik.analytic.polyroots).
 *
 * With t = tan(delta / 2) F becomes a polynomial H(t); its real roots in [-1, 1] (and those of
 * the reversed polynomial, for |delta| >= pi/2) are found by derivative recursion:
 * p_j = j-th derivative of p (degree d - j). Between two consecutive real roots of
 * p_{j+1} (and the ends -1, 1) p_j is monotone, so it has a root there iff it changes
 * sign, found by Newton's method safeguarded by bisection (started at the regula falsi
 * point). Going from j = d - 1 down to j = 0 yields every root of p in [-1, 1] where p
 * changes sign. A critical point where |p_j| <= tol * sum|coefficients| is reported too
 * (a double root, or two roots closer than rounding can separate): callers use the roots
 * as candidates, so an extra one is harmless.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#define QPIK_MAXD 32
#define QPIK_MAXR (4 * QPIK_MAXD)

/* A Newton step shorter than this ends the iteration: it converges quadratically from a bracket on
 * which p is monotone, so the returned point is then within ~1e-14 of the root (x in [-1, 1]). */
#define NEWTON_DONE 1e-8

static double horner(const double *a, int d, double x, double *deriv) {
    double f = a[d], df = 0.0;
    for (int i = d - 1; i >= 0; --i) {
        df = df * x + f;
        f = f * x + a[i];
    }
    *deriv = df;
    return f;
}

static double value(const double *a, int d, double x) {
    double f = a[d];
    for (int i = d - 1; i >= 0; --i) f = f * x + a[i];
    return f;
}

/* The root of the monotone p (degree d) in [lo, hi], where p(lo) = flo and p(hi) = fhi have opposite
 * signs. Iterates until the step is below NEWTON_DONE, not until |p| is below a rounding bound: near
 * a wrist singularity the breakpoint equations are small everywhere, far below such a bound, yet
 * their roots are well defined. */
static double bracketed(const double *a, int d, double lo, double hi, double flo, double fhi) {
    double x = lo + (hi - lo) * flo / (flo - fhi), df;
    for (int it = 0; it < 200; ++it) {
        double f = horner(a, d, x, &df);
        if (f == 0.0) return x;
        if ((f < 0.0) == (flo < 0.0)) lo = x; else hi = x;
        double next = (df != 0.0) ? x - f / df : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (fabs(next - x) <= NEWTON_DONE || hi - lo <= 4.0 * DBL_EPSILON) return next;
        x = next;
    }
    return x;
}

static int push(double *r, int n, double x) {
    if (n > 0 && fabs(x - r[n - 1]) <= 4.0 * DBL_EPSILON) return n;
    if (n >= QPIK_MAXR) return n;
    r[n] = x;
    return n + 1;
}

/* Roots in [-1, 1] of p (degree d) given the sorted roots crit[0..nc) of p'; returns their number. */
static int level(const double *a, int d, const double *crit, int nc, double tol, double *out) {
    double scale = 0.0;
    for (int i = 0; i <= d; ++i) scale += fabs(a[i]);
    if (scale == 0.0) return 0; /* p == 0: no information, no roots */
    int n = 0;
    double lo = -1.0, flo = value(a, d, lo);
    if (flo == 0.0) n = push(out, n, lo);
    for (int k = 0; k <= nc; ++k) {
        double hi = (k < nc) ? crit[k] : 1.0;
        double fhi = value(a, d, hi);
        if (flo != 0.0 && fhi != 0.0 && (flo < 0.0) != (fhi < 0.0))
            n = push(out, n, bracketed(a, d, lo, hi, flo, fhi));
        if (fhi == 0.0 || (k < nc && fabs(fhi) <= tol * scale)) n = push(out, n, hi);
        lo = hi;
        flo = fhi;
    }
    return n;
}

/* Roots of p (degree d <= QPIK_MAXD, lowest first) in [-1, 1], ascending, into roots; returns their number. */
static int real_roots(const double *p, int d, double tol, double *roots) {
    double der[QPIK_MAXD + 1][QPIK_MAXD + 1], buf[2][QPIK_MAXR];
    while (d > 0 && p[d] == 0.0) --d;
    memcpy(der[0], p, (size_t)(d + 1) * sizeof(double));
    for (int j = 1; j <= d; ++j) { /* der[j] = p^(j), each normalised: roots do not depend on scale */
        double m = 0.0;
        for (int i = 0; i <= d - j; ++i) m = fmax(m, fabs(der[j][i] = (i + 1) * der[j - 1][i + 1]));
        if (m > 0.0)
            for (int i = 0; i <= d - j; ++i) der[j][i] /= m;
    }
    int nc = 0, cur = 0;
    for (int j = d; j >= 0; --j, cur = 1 - cur) nc = level(der[j], d - j, buf[cur], nc, tol, buf[1 - cur]);
    memcpy(roots, buf[cur], (size_t)nc * sizeof(double));
    return nc;
}

/* (1 - t^2)^i (1 + t^2)^m, lowest first, into out (degree 2 (i + m)). */
static void cs_basis(int i, int m, double *out) {
    int d = 0;
    out[0] = 1.0;
    for (int k = 0; k < i + m; ++k, d += 2) { /* multiply by 1 - t^2 (first i times), then by 1 + t^2 */
        double sgn = (k < i) ? -1.0 : 1.0;
        out[d + 2] = 0.0;
        out[d + 1] = 0.0;
        for (int j = d + 2; j >= 2; --j) out[j] += sgn * out[j - 2];
    }
}

/* Real roots delta in [-pi, pi] of F(delta) = A(cos delta) + sin delta * B(cos delta), K rows of
 * coefficients (lowest first) in A (K, na + 1) and B (K, na + 1). Per row, with
 * n = max(deg A, deg B + 1) <= QPIK_MAXD / 2 and t = tan(delta / 2) (cos delta = (1 - t^2) / (1 + t^2),
 * sin delta = 2t / (1 + t^2)):
 * H(t) = (1 + t^2)^n F = sum_i a_i (1 - t^2)^i (1 + t^2)^(n-i) + 2t sum_i b_i (1 - t^2)^i (1 + t^2)^(n-1-i),
 * a polynomial of degree 2n with the same real roots (delta = 2 atan t). Its roots with |t| <= 1
 * (|delta| <= pi/2) and those of t^(2n) H(1/t) with |1/t| <= 1 (|delta| >= pi/2) cover the circle,
 * each where d delta / dt is between 1 and 2: well conditioned everywhere. Writes row k's roots to
 * delta[k * 2 * QPIK_MAXR ...] and their number to count[k]; returns -1 if a degree is too large. */
int qpik_trig_roots(int K, int na, const double *A, const double *B, double tol, double *delta, int *count) {
    double H[QPIK_MAXD + 1], rev[QPIK_MAXD + 1], basis[QPIK_MAXD + 3], t[QPIK_MAXR];
    for (int k = 0; k < K; ++k) {
        const double *a = A + (long)k * (na + 1), *b = B + (long)k * (na + 1);
        int da = na, db = na, m = 0, nr;
        while (da >= 0 && a[da] == 0.0) --da;
        while (db >= 0 && b[db] == 0.0) --db;
        int n = da > db + 1 ? da : db + 1, d = 2 * n;
        count[k] = 0;
        if (d > QPIK_MAXD) return -1;
        if (n <= 0) continue; /* F constant: no roots (or all of them: no information) */
        memset(H, 0, sizeof H);
        for (int i = 0; i <= da; ++i) {
            cs_basis(i, n - i, basis);
            for (int j = 0; j <= d; ++j) H[j] += a[i] * basis[j];
        }
        for (int i = 0; i <= db; ++i) {
            cs_basis(i, n - 1 - i, basis);
            for (int j = 0; j <= d - 2; ++j) H[j + 1] += 2.0 * b[i] * basis[j]; /* basis has degree d - 2 */
        }
        for (int j = 0; j <= d; ++j) rev[j] = H[d - j];
        double *out = delta + (long)k * 2 * QPIK_MAXR;
        nr = real_roots(H, d, tol, t);
        for (m = 0; m < nr; ++m) out[m] = 2.0 * atan(t[m]);
        nr = real_roots(rev, d, tol, t);
        for (int i = 0; i < nr; ++i) /* u = 1/t: delta = 2 atan(1/u) = sign(u) pi - 2 atan(u), pi at u = 0 */
            out[m++] = (t[i] < 0.0 ? -1.0 : 1.0) * 3.14159265358979323846 - 2.0 * atan(t[i]);
        count[k] = m;
    }
    return 0;
}

int qpik_max_roots(void) { return QPIK_MAXR; }
