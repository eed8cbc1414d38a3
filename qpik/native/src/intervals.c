/* Feasible parameter sets on the circle from breakpoints (qpik.analytic.intervals.SetAssembler).
 *
 * The breakpoints are wrapped to (-pi, pi], sorted and merged within SAME; they cut the circle into
 * gaps, and one evaluation of the branches at each gap's midpoint (the compiled, CasADi-generated IK
 * with its limit test, called through its C entry point) says in which gaps each branch is feasible.
 * Each branch's runs of feasible gaps are its set, split at +-pi. With shift, the same sets moved by
 * pi are written after them (the offset-shoulder rows 9-16 are rows 1-8 at delta + pi). The candidate
 * singular values are evaluated as well and kept, per branch, where it is valid and singular.
 */
#include <stdlib.h>
#include <string.h>

#include "circle.h"
#include "intervals.h"

#ifndef SAME
#error "SAME (rad, qpik.analytic.intervals.SAME: breakpoints closer than this are one) is given by -DSAME=..."
#endif

static int ascending(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Up to this many items are sorted by insertion (faster than qsort's calls of `ascending` at these sizes). */
#define FEW 64

/* Sorts n items of `width` doubles by their first double, ascending. */
static void sort_items(double *x, int n, int width) {
    if (n > FEW) {
        qsort(x, (size_t)n, (size_t)width * sizeof(double), ascending);
        return;
    }
    for (int i = 1; i < n; ++i) {
        double item[2] = {x[width * i], width > 1 ? x[width * i + 1] : 0.0};
        int j = i;
        for (; j > 0 && x[width * (j - 1)] > item[0]; --j)
            for (int k = 0; k < width; ++k) x[width * j + k] = x[width * (j - 1) + k];
        for (int k = 0; k < width; ++k) x[width * j + k] = item[k];
    }
}

/* Whether x lies outside the call's region (to SAME); never without a region. */
static int outside(const Call *c, double x) {
    if (!c->n_region || *c->n_region < 0) return 0;
    for (int i = 0; i < *c->n_region; ++i)
        if (x >= c->region[2 * i] - SAME && x <= c->region[2 * i + 1] + SAME) return 0;
    return 1;
}

static const double *evaluate(const Call *c, double x) {
    *c->param = x;
    return c->fn(c->arg, c->res, c->iw, c->w, 0) ? NULL : c->res[1];
}

/* One branch's set from its feasible gaps: gap i is [lo[i], lo[i + 1]] (lo sorted, in (-pi, pi]), the
 * last one [lo[G - 1], lo[0] + 2 pi]; ok[i] says it is feasible. Writes sorted disjoint pieces of
 * [-pi, pi] to out (pairs, at most G + 1) and returns how many. */
static int runs(int G, const double *lo, const unsigned char *ok, double *out) {
    int bad = -1;
    for (int i = 0; i < G && bad < 0; ++i)
        if (!ok[i]) bad = i;
    if (bad < 0) {
        out[0] = -PI, out[1] = PI;
        return 1;
    }
    int n = 0;
    for (int i = 1; i <= G;) { /* gaps bad + 1, ..., bad + G (mod G): every run is whole */
        int s = bad + i < G ? bad + i : bad + i - G;
        if (!ok[s]) {
            ++i;
            continue;
        }
        int e = s;
        for (++i; i <= G; ++i) {
            int g = bad + i < G ? bad + i : bad + i - G;
            if (!ok[g]) break;
            e = g;
        }
        double a = lo[s];
        if (e < s) { /* through gap G - 1 into gap 0: split at +-pi */
            out[2 * n] = a, out[2 * n + 1] = PI, ++n;
            out[2 * n] = -PI, out[2 * n + 1] = lo[e + 1], ++n;
        } else if (e == G - 1) { /* gap G - 1 passes pi (lo[0] + 2 pi > pi) */
            out[2 * n] = a, out[2 * n + 1] = PI, ++n;
            out[2 * n] = -PI, out[2 * n + 1] = lo[0], ++n;
        } else {
            out[2 * n] = a, out[2 * n + 1] = lo[e + 1], ++n;
        }
    }
    sort_items(out, n, 2);
    return n;
}

/* The feasible sets of the rows (intervals.h). */
int circle_sets(const Call *call, int rows, int shift, int nb, const double *breaks, int ns, const double *sing,
                int room, double *iv, int *count, double *sv, int *scount) {
    int G = nb > 0 ? nb : 1, out_rows = shift ? 2 * rows : rows, status = 0, used = 0;
    double *lo = malloc(sizeof(double) * (2 * (size_t)G + (size_t)ns + 2 * ((size_t)G + 1)));
    unsigned char *ok = malloc((size_t)G * (size_t)rows * 2);
    if (!lo || !ok) {
        free(lo), free(ok);
        return -3;
    }
    double *lo2 = lo + G, *s = lo2 + G, *piece = s + ns;
    unsigned char *ok2 = ok + (size_t)G * rows;

    /* the gaps */
    if (nb == 0) lo[0] = 0.0;
    for (int i = 0; i < nb; ++i) lo[i] = wrap(breaks[i]);
    sort_items(lo, G, 1);
    int g = 1;
    for (int i = 1; i < G; ++i) /* one breakpoint per cluster within SAME (consecutive differences) */
        if (lo[i] - lo[i - 1] > SAME) lo[g++] = lo[i];
    G = g;

    /* classify: ok[r * G + i] */
    for (int i = 0; i < G && !status; ++i) {
        double hi = i + 1 < G ? lo[i + 1] : lo[0] + TWO_PI, mid = wrap(0.5 * (lo[i] + hi));
        if (outside(call, mid)) {
            for (int r = 0; r < rows; ++r) ok[(size_t)r * G + i] = 0;
            continue;
        }
        const double *f = evaluate(call, mid);
        if (!f) status = -2;
        for (int r = 0; r < rows && f; ++r) ok[(size_t)r * G + i] = f[2 * rows + r] > 0.5;
    }

    /* the sets moved by pi: gap k + j (mod G) becomes gap j, k = the first gap with lo > 0 */
    int k = 0;
    while (k < G && !(lo[k] + PI > PI)) ++k;
    for (int j = 0; j < G && shift; ++j) {
        int i = (k + j) % G;
        lo2[j] = j < G - k ? lo[i] + PI - TWO_PI : lo[i] + PI;
        for (int r = 0; r < rows; ++r) ok2[(size_t)r * G + j] = ok[(size_t)r * G + i];
    }
    for (int r = 0; r < out_rows && !status; ++r) {
        int n = r < rows ? runs(G, lo, ok + (size_t)r * G, piece) : runs(G, lo2, ok2 + (size_t)(r - rows) * G, piece);
        if (used + n > room) {
            status = -1;
            break;
        }
        memcpy(iv + 2 * used, piece, sizeof(double) * 2 * (size_t)n);
        count[r] = n, used += n;
    }

    /* singular values: valid and singular there */
    for (int i = 0; i < ns; ++i) s[i] = wrap(sing[i]);
    sort_items(s, ns, 1);
    for (int r = 0; r < out_rows; ++r) scount[r] = 0;
    for (int i = 0; i < ns && !status; ++i) {
        if (i > 0 && s[i] == s[i - 1]) continue;
        const double *f = evaluate(call, s[i]);
        if (!f) status = -2;
        for (int r = 0; r < rows && f; ++r) {
            if (f[r] <= 0.5 || f[rows + r] <= 0.5) continue;
            sv[(size_t)r * ns + scount[r]++] = s[i];
            if (shift) sv[(size_t)(rows + r) * ns + scount[rows + r]++] = wrap(s[i] + PI);
        }
    }
    for (int r = rows; r < out_rows; ++r) sort_items(sv + (size_t)r * ns, scount[r], 1);
    free(lo), free(ok);
    return status ? status : used;
}

/* circle_sets with the compiled IK fn (CasADi's calling convention): arg, res, iw, w are its argument and result
 * pointers and work arrays (arg[1] = param, res[1] = flags of 3 rows values: valid, singular, within limits per
 * branch). */
int qpik_circle_sets(void *fn, const double **arg, double **res, casadi_int *iw, double *w, double *param,
                     int rows, int shift, int nb, const double *breaks, int ns, const double *sing, int room,
                     double *iv, int *count, double *sv, int *scount) {
    Call call = {(casadi_fn)fn, arg, res, iw, w, param, NULL, NULL};
    return circle_sets(&call, rows, shift, nb, breaks, ns, sing, room, iv, count, sv, scount);
}
