/* Real roots of F(delta) = A(cos delta) + sin delta B(cos delta) (qpik.analytic.polyroots).
 *
 * With t = tan(delta / 2) F becomes a polynomial H(t); its real roots in [-1, 1] (and those of
 * the reversed polynomial, for |delta| >= pi/2) are found between its critical points, which are
 * isolated by Descartes' rule of signs in the Bernstein basis (real_roots below). Callers use the
 * roots as candidates, so an extra one (a near-double root reported at its critical point) is harmless.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "polyroots.h"

#define QPIK_MAXD 32
#define QPIK_MAXR (4 * QPIK_MAXD)

/* A Newton step shorter than this ends the iteration (x in [-1, 1]): the root to rounding, also where
 * the quadratic convergence constant is large (near an elbow singularity a wrist angle turns through pi
 * within 1e-7 rad of delta). */
#define NEWTON_DONE (4.0 * DBL_EPSILON)

/* p(x) and p'(x) (degree d, lowest first) as E(y) + x O(y) and 2x E'(y) + O(y) + 2y O'(y), y = x^2, E and O the
 * even and odd parts: two independent Horner chains of half the length (Newton's iterations spend their time
 * here, waiting on the chain). */
static double horner(const double *a, int d, double x, double *deriv) {
    int m = d / 2; /* E: a[0], a[2], ..., a[2m]; O: a[1], a[3], ..., a[d] for odd d (its top below, 0 for even d) */
    double y = x * x, e = a[2 * m], de = 0.0, o = (d % 2) ? a[d] : 0.0, dov = 0.0;
    for (int k = m - 1; k >= 0; --k) {
        de = de * y + e;
        e = e * y + a[2 * k];
        dov = dov * y + o;
        o = o * y + a[2 * k + 1];
    }
    *deriv = 2.0 * x * de + o + 2.0 * y * dov;
    return e + x * o;
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
        if (fabs(next - x) <= NEWTON_DONE) return fmin(fmax(next, lo), hi); /* before the bracket test: x is an end */
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (hi - lo <= 4.0 * DBL_EPSILON) return next;
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

/* Sign changes of b[0..d], zeros skipped. */
static int variations(const double *b, int d) {
    int v = 0, last = 0;
    for (int k = 0; k <= d; ++k) {
        int sg = (b[k] > 0.0) - (b[k] < 0.0);
        if (sg && last && sg != last) ++v;
        if (sg) last = sg;
    }
    return v;
}

/* The roots of p (degree d <= QPIK_MAXD, lowest first) in [-1, 1], ascending, into out; returns their number.
 * A root is a point (lo == hi) or, where p changes sign once in [lo, hi] (flo = p(lo), fhi = p(hi) of opposite
 * signs), that bracket: its caller decides whether it needs the root itself (level below).
 *
 * Isolation by Descartes' rule in the Bernstein basis: on an interval, the number of sign changes V of
 * p's Bernstein coefficients bounds the number of roots (and has its parity). V = 0: none; V = 1: exactly
 * one, a sign change (a bracket); V >= 2: the interval is halved (de Casteljau). An
 * interval narrower than ISOLATE_WIDTH that still has V >= 2 (a double root, or roots closer than that)
 * is reported by its midpoint. Rounding can make V = 0 next to a near-double root, so real_roots below
 * uses this for p' only. */
typedef struct {
    double lo, hi, flo, fhi;
} Root;

static int add_point(Root *r, int n, double x) {
    if (n > 0 && r[n - 1].lo == r[n - 1].hi && fabs(x - r[n - 1].hi) <= 4.0 * DBL_EPSILON) return n;
    if (n >= QPIK_MAXR) return n;
    r[n] = (Root){x, x, 0.0, 0.0};
    return n + 1;
}

#define ISOLATE_WIDTH 1e-10
static int bernstein_roots(const double *p, int d, Root *roots) {
    double q[QPIK_MAXD + 1], b[QPIK_MAXD + 1];
    while (d > 0 && p[d] == 0.0) --d;
    if (d == 0) return 0;
    /* q(y) = p(2y - 1) on y in [0, 1] */
    memset(q, 0, sizeof q);
    q[0] = p[d];
    for (int i = d - 1; i >= 0; --i) { /* q <- q (2y - 1) + p_i */
        for (int k = d - i; k >= 1; --k) q[k] = 2.0 * q[k - 1] - q[k];
        q[0] = -q[0] + p[i];
    }
    /* b_k = sum_i C(k,i) q_i / C(d,i): scale by 1/C(d,i), then the binomial transform by Pascal sums */
    double cdi = 1.0;
    for (int i = 0; i <= d; ++i) {
        b[i] = q[i] / cdi;
        cdi = cdi * (d - i) / (i + 1);
    }
    for (int j = 1; j <= d; ++j)
        for (int k = d; k >= j; --k) b[k] += b[k - 1];
    /* depth-first over intervals [x0, x1] of x, left half first: roots come out ascending */
    double stack_b[64][QPIK_MAXD + 1], stack_x[64][2];
    int top = 0, n = 0;
    memcpy(stack_b[0], b, (size_t)(d + 1) * sizeof(double));
    stack_x[0][0] = -1.0;
    stack_x[0][1] = 1.0;
    top = 1;
    while (top > 0) {
        --top;
        double *c = stack_b[top], x0 = stack_x[top][0], x1 = stack_x[top][1];
        if (c[0] == 0.0) n = add_point(roots, n, x0);
        int v = variations(c, d);
        if (v == 0) continue;
        if (v == 1) { /* one root inside: a sign change of p, unless rounding or a root at an end hides it */
            double f0 = value(p, d, x0), f1 = value(p, d, x1);
            if (f0 != 0.0 && f1 != 0.0 && (f0 < 0.0) != (f1 < 0.0)) {
                if (n < QPIK_MAXR) roots[n++] = (Root){x0, x1, f0, f1};
                continue;
            }
        }
        if (x1 - x0 <= ISOLATE_WIDTH || top >= 62) {
            n = add_point(roots, n, 0.5 * (x0 + x1));
            continue;
        }
        /* de Casteljau at the midpoint: left half into slot top + 1, right half into slot top */
        double *left = stack_b[top + 1], tmp[QPIK_MAXD + 1];
        memcpy(tmp, c, (size_t)(d + 1) * sizeof(double));
        left[0] = tmp[0];
        for (int r = 1; r <= d; ++r) {
            for (int k = 0; k <= d - r; ++k) tmp[k] = 0.5 * (tmp[k] + tmp[k + 1]);
            left[r] = tmp[0];
            c[d - r] = tmp[d - r];
        }
        double xm = 0.5 * (x0 + x1);
        stack_x[top][0] = xm; /* right half stays in slot top, with c overwritten */
        stack_x[top + 1][0] = x0;
        stack_x[top + 1][1] = xm;
        top += 2;
    }
    if (b[d] == 0.0) n = add_point(roots, n, 1.0);
    return n;
}

/* Roots in [-1, 1] of p (degree d) given the sorted critical points crit[0..nc) (roots of p', whose
 * coefficients are dp, as bernstein_roots gives them: points or brackets); returns their number. Between
 * consecutive critical points (and the ends) p is monotone: a sign change there is one root. A critical
 * point where |p| <= TOL sum|p_i| is reported too: a double root, or two roots closer than rounding separates
 * (an extra candidate is harmless).
 *
 * A bracket [lo, hi] of a critical point holds one extremum of p, no other: where |p(lo)| and |p(hi)| exceed
 * TOL sum|p_i| and either p changes sign in it (one root, found in [lo, hi]) or the extremum lies on the far
 * side of zero (p' has the sign of p at lo: p moves away from zero, no root), |p| at the extremum exceeds
 * TOL sum|p_i| as well, so the critical point itself is not needed: lo and hi take its place. Otherwise it is
 * found by safeguarded Newton on p'. */
#define TOL 1e-12
typedef struct {
    const double *a;
    int d;
    double bound; /* TOL sum|p_i| */
    double x, fx; /* the last point */
    double *out;
    int n;
} Scan;

/* The scan moves on to y, where p = fy: the root of a sign change since the last point, y itself where p = 0 or
 * where y is a critical point with |p| <= bound. */
static void advance(Scan *s, double y, double fy, int critical) {
    if (s->fx != 0.0 && fy != 0.0 && (s->fx < 0.0) != (fy < 0.0))
        s->n = push(s->out, s->n, bracketed(s->a, s->d, s->x, y, s->fx, fy));
    if (fy == 0.0 || (critical && fabs(fy) <= s->bound)) s->n = push(s->out, s->n, y);
    s->x = y;
    s->fx = fy;
}

static int level(const double *a, int d, const double *dp, const Root *crit, int nc, double *out) {
    double scale = 0.0;
    for (int i = 0; i <= d; ++i) scale += fabs(a[i]);
    if (scale == 0.0) return 0; /* p == 0: no information, no roots */
    Scan s = {a, d, TOL * scale, -1.0, value(a, d, -1.0), out, 0};
    if (s.fx == 0.0) s.n = push(out, s.n, -1.0);
    for (int k = 0; k < nc; ++k) {
        const Root *r = &crit[k];
        double c = r->lo;
        if (r->lo < r->hi) {
            double f0 = value(a, d, r->lo), f1 = value(a, d, r->hi);
            int away = (f0 < 0.0) != (f1 < 0.0) || (f0 > 0.0) == (r->flo > 0.0);
            if (fabs(f0) > s.bound && fabs(f1) > s.bound && away) {
                advance(&s, r->lo, f0, 0);
                advance(&s, r->hi, f1, 0);
                continue;
            }
            c = bracketed(dp, d - 1, r->lo, r->hi, r->flo, r->fhi);
        }
        advance(&s, c, value(a, d, c), 1);
    }
    advance(&s, 1.0, value(a, d, 1.0), 0);
    return s.n;
}

/* Roots of p (degree d <= QPIK_MAXD, lowest first) in [-1, 1], ascending: the critical points (roots of p')
 * by Bernstein isolation, then one root per sign change of p between them (level). */
static int real_roots(const double *p, int d, double *roots) {
    double dp[QPIK_MAXD + 1];
    Root crit[QPIK_MAXR];
    while (d > 0 && p[d] == 0.0) --d;
    if (d == 0) return 0;
    for (int i = 0; i < d; ++i) dp[i] = (i + 1) * p[i + 1];
    int nc = d >= 2 ? bernstein_roots(dp, d - 1, crit) : 0;
    return level(p, d, dp, crit, nc, roots);
}

/* sum_{i=0..m} c_i (1 - t^2)^i (1 + t^2)^(m-i) into out (degree 2m, lowest first), by Horner in
 * u = 1 - t^2: P <- P u + c_i w^(m-i), with the powers of w = 1 + t^2 built along. */
static void cs_poly(const double *c, int m, double *out) {
    double w[QPIK_MAXD + 1];
    int dw = 0; /* w holds (1 + t^2)^(m - i), degree dw */
    memset(out, 0, (size_t)(2 * m + 1) * sizeof(double));
    memset(w, 0, sizeof w);
    w[0] = 1.0;
    out[0] = c[m];
    for (int i = m - 1, dp = 0; i >= 0; --i, dp += 2) {
        for (int j = dp + 2; j >= 2; --j) out[j] = out[j] - out[j - 2]; /* P (1 - t^2) */
        for (int j = dw + 2; j >= 2; --j) w[j] += w[j - 2]; /* w (1 + t^2) */
        dw += 2;
        for (int j = 0; j <= dw; ++j) out[j] += c[i] * w[j];
    }
}

/* Real roots delta in [-pi, pi] of F(delta) = A(cos delta) + sin delta * B(cos delta), K rows of
 * coefficients (lowest first) in A (K, na + 1) and B (K, na + 1). Per row, with
 * n = max(deg A, deg B + 1) <= QPIK_MAXD / 2 and t = tan(delta / 2) (cos delta = (1 - t^2) / (1 + t^2),
 * sin delta = 2t / (1 + t^2)):
 * H(t) = (1 + t^2)^n F = sum_i a_i (1 - t^2)^i (1 + t^2)^(n-i) + 2t sum_i b_i (1 - t^2)^i (1 + t^2)^(n-1-i),
 * a polynomial of degree 2n with the same real roots (delta = 2 atan t). Its roots with |t| <= 1
 * (|delta| <= pi/2) and those of t^(2n) H(1/t) with |1/t| <= 1 (|delta| >= pi/2) cover the circle,
 * each where d delta / dt is between 1 and 2: well conditioned everywhere. Writes the roots of all rows
 * to delta and the row of each to owner (room for `room` of them); returns their number, or -1 if a
 * degree is too large or the room too small. */
int qpik_trig_roots(int K, int na, const double *A, const double *B, int room, double *delta, int *owner) {
    int m = 0;
    double H[QPIK_MAXD + 3], rev[QPIK_MAXD + 1], t[QPIK_MAXR];
    for (int k = 0; k < K; ++k) {
        const double *a = A + (long)k * (na + 1), *b = B + (long)k * (na + 1);
        int da = na, db = na, nr;
        while (da >= 0 && a[da] == 0.0) --da;
        while (db >= 0 && b[db] == 0.0) --db;
        int n = da > db + 1 ? da : db + 1, d = 2 * n;
        if (d > QPIK_MAXD) return -1;
        if (n <= 0) continue; /* F constant: no roots (or all of them: no information) */
        double ca[QPIK_MAXD / 2 + 1], cb[QPIK_MAXD / 2 + 1], hb[QPIK_MAXD + 1];
        for (int i = 0; i <= n; ++i) ca[i] = (i <= da) ? a[i] : 0.0;
        for (int i = 0; i < n; ++i) cb[i] = (i <= db) ? b[i] : 0.0;
        cs_poly(ca, n, H);
        cs_poly(cb, n - 1, hb);
        for (int j = 0; j <= d - 2; ++j) H[j + 1] += 2.0 * hb[j];
        for (int j = 0; j <= d; ++j) rev[j] = H[d - j];
        nr = real_roots(H, d, t);
        if (m + nr > room) return -1;
        for (int i = 0; i < nr; ++i, ++m) {
            delta[m] = 2.0 * atan(t[i]);
            owner[m] = k;
        }
        nr = real_roots(rev, d, t);
        if (m + nr > room) return -1;
        for (int i = 0; i < nr; ++i, ++m) { /* u = 1/t: delta = 2 atan(1/u) = sign(u) pi - 2 atan(u), pi at u = 0 */
            delta[m] = (t[i] < 0.0 ? -1.0 : 1.0) * 3.14159265358979323846 - 2.0 * atan(t[i]);
            owner[m] = k;
        }
    }
    return m;
}

