/* The joint-limit margin's maximum over its super-level sets, one pose per call (qpik.nlp.levelset).
 *
 * The rounds of qpik.nlp.levelset.maximise with its two compiled parts called from here: the arm's feasible sets
 * under limits written into their buffers (NativeSets: the breakpoint function, the root finder and the gap
 * classification, one C call) and the self-motion of a branch row, q and dq/dpsi at one parameter (CasADi's
 * generated C). The trial points are those of qpik.nlp.levelset._trials (a point equal to the one before it is not
 * evaluated again), the climb that of _climb, the margin and its slope those of
 * qpik.objectives.JointLimitMargin (the active term of the minimum). The tests compare this path with the
 * Python one.
 */
#include <math.h>
#include <string.h>

#include "casadi_call.h"
#include "circle.h"

typedef int (*sets_fn)(const void *context);

#define TRIALS 3

typedef struct {
    void *sets;          /* int sets(const void *context): the feasible sets of the pose and limits in its buffers */
    const void *context;
    double *sets_pose;   /* its pose buffer (16, column-major) */
    double *sets_lo;     /* its limit buffers (n) */
    double *sets_hi;
    const double *iv;    /* its output: count[r] pieces of row r, (lo, hi) pairs one row after the other */
    const int *count;
    double *region;      /* its region: where the sets can be (region_room pairs), in n_region[0] pairs, -1: none */
    int *n_region;
    int region_room;
    int rows;            /* the searched rows: the first rows of its output */
    Kernel motion;       /* (branch row, pose (16), psi) -> [q (n); dq/dpsi (n); valid] */
    double *motion_row, *motion_pose, *motion_psi;
    const double *motion_out;
    int n;
    const double *q_min, *q_max; /* (n) */
    double eps, end, near, slack;
    int climb;          /* steps of a climb at most */
    int max_rounds;
    int room;            /* pieces per round at most */
    double *work;        /* 24 * room doubles */
} LevelSet;

/* Pieces of one round: [lo, hi] of branch row `row`, and its trial points x with mu and dmu/dpsi there. */
typedef struct {
    double *lo, *hi, *row, *x, *mu, *slope; /* x, mu, slope: TRIALS per piece */
    int count;
} Pieces;

static Pieces pieces_at(double *work, int room) {
    Pieces p = {work, work + room, work + 2 * room, work + 3 * room, work + 6 * room, work + 9 * room, 0};
    return p;
}

/* The margin mu and dmu/dpsi of branch row `row` at psi; mu = -inf where the branch does not reach the pose. */
static int margin_at(const LevelSet *L, int row, double psi, double *mu, double *slope) {
    const Kernel *k = &L->motion;
    *L->motion_row = row;
    *L->motion_psi = wrap(psi);
    if (((casadi_fn)k->fn)(k->arg, k->res, k->iw, k->w, 0)) return -2;
    const double *q = L->motion_out, *dq = q + L->n;
    *mu = -INFINITY, *slope = NAN;
    if (!(q[2 * L->n] > 0.5)) return 0;
    double best = INFINITY, rate = NAN;
    for (int j = 0; j < L->n; ++j) {
        if (!isfinite(q[j])) return 0; /* as a non-finite objective in Python: no point */
        double half = 0.5 * (L->q_max[j] - L->q_min[j]);
        double below = (q[j] - L->q_min[j]) / half, above = (L->q_max[j] - q[j]) / half;
        if (below < best) best = below, rate = dq[j] / half;
        if (above < best) best = above, rate = -dq[j] / half;
    }
    if (isfinite(best)) *mu = best, *slope = rate;
    return 0;
}

/* The trial points of piece i of `now` (qpik.nlp.levelset._trials), from its parent in `before` (NULL in the first
 * round: the middle, in all three slots). */
static void trials(const LevelSet *L, const Pieces *now, int i, double level, const Pieces *before,
                   double before_level, double *t) {
    double a = now->lo[i], b = now->hi[i], mid = 0.5 * (a + b);
    double e = fmin(L->end, 0.25 * (b - a));
    t[0] = t[1] = t[2] = mid;
    if (!before) return;
    int k = -1;
    for (int j = 0; j < before->count && k < 0; ++j)
        if (before->row[j] == now->row[i] && before->lo[j] <= a + L->slack && b <= before->hi[j] + L->slack) k = j;
    if (k < 0) return;
    double slope_at[2], px[2], ps[2];
    int has[2];
    for (int side = 0; side < 2; ++side) {
        double end = side ? b : a, p_end = side ? before->hi[k] : before->lo[k], sign = side ? -1.0 : 1.0;
        int top = -1;
        for (int j = 0; j < TRIALS; ++j) {
            double d = before->slope[TRIALS * k + j], f = before->mu[TRIALS * k + j];
            if (sign * d > 0 && (top < 0 || f > before->mu[TRIALS * k + top])) top = j;
        }
        has[side] = top >= 0;
        if (top >= 0) {
            double x = before->x[TRIALS * k + top];
            x += TWO_PI * round((mid - x) / TWO_PI); /* beside this piece (one may pass pi) */
            double f = before->mu[TRIALS * k + top], d = before->slope[TRIALS * k + top];
            px[side] = x, ps[side] = d;
            slope_at[side] = fabs(end - x) <= L->near ? d : 2.0 * (level - f) / (end - x) - d;
        } else {
            slope_at[side] = end != p_end ? (level - before_level) / (end - p_end) : sign * INFINITY;
        }
    }
    double sl = slope_at[0], sr = slope_at[1];
    double cross = sl > 0 && sr < 0 && isfinite(sl - sr) ? (sl * a - sr * b) / (sl - sr) : mid;
    double root;
    if (has[0] && has[1] && ps[0] != ps[1])
        root = px[0] - ps[0] * (px[1] - px[0]) / (ps[1] - ps[0]);
    else
        root = has[0] ? b - e : a + e;
    t[1] = fmin(fmax(cross, a), b);
    t[2] = isfinite(root) ? fmin(fmax(root, a), b) : mid;
}


/* Evaluates branch row `row` at x (mu and dmu/dpsi out) and keeps it as the row's best point when it is better. */
static int visit(const LevelSet *L, int row, double x, double *mu, double *slope, double *best_mu, double *best_psi,
                 double *best_q, int *evals) {
    if (margin_at(L, row, x, mu, slope)) return -2;
    ++evals[row];
    if (*mu > best_mu[row]) {
        best_mu[row] = *mu, best_psi[row] = wrap(x);
        memcpy(best_q + (size_t)row * L->n, L->motion_out, (size_t)L->n * sizeof(double));
    }
    return 0;
}

/* The climb of qpik.nlp.levelset._climb on piece i of `now` (its trial points evaluated), raising *top. */
static int climb(const LevelSet *L, const Pieces *now, int i, double level, double *top, double *best_mu,
                 double *best_psi, double *best_q, int *evals) {
    double lx = now->lo[i], lm = level, ls = NAN, rx = now->hi[i], rm = level, rs = NAN;
    int lk = 0, rk = 0, row = (int)now->row[i];
    for (int j = 0; j < TRIALS; ++j) {
        double x = now->x[TRIALS * i + j], m = now->mu[TRIALS * i + j], s = now->slope[TRIALS * i + j];
        if (s > 0 && (!lk || m > lm)) lx = x, lm = m, ls = s, lk = 1;
        if (s < 0 && (!rk || m > rm)) rx = x, rm = m, rs = s, rk = 1;
    }
    if (!lk && !rk) return 0;
    for (int it = 0; it < L->climb && rx - lx > L->slack; ++it) {
        double sl = lk ? ls : 2.0 * (lm - rm) / (lx - rx) - rs;
        double sr = rk ? rs : 2.0 * (rm - lm) / (rx - lx) - ls;
        if (!(sl > 0 && sr < 0 && isfinite(sl - sr))) return 0;
        double cross = (rm - lm + sl * lx - sr * rx) / (sl - sr);
        if (lm + sl * (cross - lx) - *top < 0.5 * L->eps) return 0;
        double t[2] = {cross, lk && rk ? lx - ls * (rx - lx) / (rs - ls) : NAN};
        for (int j = 0; j < 2; ++j) {
            double x = t[j], m, s;
            if (!(x > lx && x < rx)) continue;
            if (visit(L, row, x, &m, &s, best_mu, best_psi, best_q, evals)) return -2;
            if (m > *top) *top = m;
            if (s > 0)
                lx = x, lm = m, ls = s, lk = 1;
            else if (s < 0)
                rx = x, rm = m, rs = s, rk = 1;
            else
                return 0; /* the top itself, or no point */
        }
    }
    return 0;
}

/* The region of the next sets: the pieces of this round, split at +-pi (-1: more than its room). */
static int region_of(const LevelSet *L, const Pieces *p) {
    int m = 0;
    for (int i = 0; i < p->count; ++i) {
        double a = p->lo[i], b = p->hi[i];
        if (m + 2 > L->region_room) return -1;
        if (b > PI) { /* a piece through +-pi */
            L->region[2 * m] = a, L->region[2 * m + 1] = PI, ++m;
            a = -PI, b -= TWO_PI;
        }
        L->region[2 * m] = a, L->region[2 * m + 1] = b, ++m;
    }
    return m;
}

/* The rounds for one pose (16, column-major). Per searched row r: best_mu[r], best_psi[r] and best_q[r n ...] (n) the
 * best point evaluated (-inf, 0 and untouched when none), rounds[r] the last round that evaluated the row, evals[r]
 * its evaluations; *level the last level.
 * Returns 1 when the maximum is proved (the sets at the last level are empty), 0 when not (a round found nothing
 * inside its own level set, or max_rounds rounds), 2 when the sets at level 0 are empty, -1 when more pieces came
 * than the sets or these rounds hold, -2 when a compiled function failed, -3 without memory (the sets' codes). */
static int rounds_of(const LevelSet *L, const double *pose, double *best_mu, double *best_psi, double *best_q,
                     int *rounds, int *evals, double *level_out);

/* The rounds of rounds_of for N poses (16 doubles each, column-major, one after the other). Per pose, out holds
 * R (n + 2) + 1 doubles: best_mu (R), best_psi (R), best_q (R n), the level; info holds 2 R + 1 ints: rounds (R),
 * evals (R), the status. Returns the first status below -1 (a failure), else 0. */
int qpik_levelset(const LevelSet *L, int N, const double *poses, double *out, int *info) {
    int R = L->rows, n = L->n, failed = 0;
    for (int i = 0; i < N; ++i) {
        double *o = out + (size_t)i * (R * (n + 2) + 1);
        int *f = info + (size_t)i * (2 * R + 1);
        f[2 * R] = rounds_of(L, poses + 16 * (size_t)i, o, o + R, o + 2 * R, f, f + R, o + R * (n + 2));
        if (f[2 * R] < -1 && !failed) failed = f[2 * R];
    }
    *L->n_region = -1; /* the sets' other callers have none */
    return failed;
}

static int rounds_of(const LevelSet *L, const double *pose, double *best_mu, double *best_psi, double *best_q,
                     int *rounds, int *evals, double *level_out) {
    int R = L->rows, n = L->n, status = 0;
    memcpy(L->sets_pose, pose, 16 * sizeof(double));
    memcpy(L->motion_pose, pose, 16 * sizeof(double));
    for (int r = 0; r < R; ++r) best_mu[r] = -INFINITY, best_psi[r] = 0.0, rounds[r] = 0, evals[r] = 0;
    Pieces buf[2] = {pieces_at(L->work, L->room), pieces_at(L->work + 12 * L->room, L->room)};
    Pieces *now = &buf[0], *before = NULL;
    double level = 0.0, before_level = 0.0, best = -INFINITY;
    for (int k = 0; k <= L->max_rounds; ++k) {
        for (int j = 0; j < n; ++j) {
            double half = level * 0.5 * (L->q_max[j] - L->q_min[j]);
            L->sets_lo[j] = L->q_min[j] + half, L->sets_hi[j] = L->q_max[j] - half;
        }
        *L->n_region = before ? region_of(L, before) : -1; /* the sets at a higher level lie inside these */
        int m = ((sets_fn)L->sets)(L->context);
        if (m < 0) return m;
        now->count = 0;
        for (int r = 0, off = 0; r < R; off += L->count[r], ++r) {
            int c = L->count[r];
            const double *v = L->iv + 2 * off;
            int first = 0, last = c;
            if (c > 1 && v[0] == -PI && v[2 * c - 1] == PI) { /* through +-pi: one piece */
                if (now->count >= L->room) return -1;
                now->lo[now->count] = v[2 * c - 2], now->hi[now->count] = v[1] + TWO_PI, now->row[now->count++] = r;
                first = 1, last = c - 1;
            }
            for (int i = first; i < last; ++i) {
                if (now->count >= L->room) return -1;
                now->lo[now->count] = v[2 * i], now->hi[now->count] = v[2 * i + 1], now->row[now->count++] = r;
            }
        }
        if (now->count == 0) {
            status = k ? 1 : 2;
            break;
        }
        if (k == L->max_rounds) break;
        double top = -INFINITY;
        for (int i = 0; i < now->count; ++i) {
            double t[TRIALS];
            trials(L, now, i, level, before, before_level, t);
            int row = (int)now->row[i];
            for (int j = 0; j < TRIALS; ++j) {
                double *x = now->x + TRIALS * i, *mu = now->mu + TRIALS * i, *slope = now->slope + TRIALS * i;
                x[j] = t[j];
                if (j && t[j] == t[j - 1]) { /* the same point (the first round's middle): the same values */
                    mu[j] = mu[j - 1], slope[j] = slope[j - 1];
                    continue;
                }
                if (visit(L, row, t[j], mu + j, slope + j, best_mu, best_psi, best_q, evals)) return -2;
                rounds[row] = k + 1;
                if (mu[j] > top) top = mu[j];
            }
        }
        int at = 0; /* the piece of the first trial point at the top */
        while (at < TRIALS * now->count - 1 && !(now->mu[at] == top)) ++at;
        if (climb(L, now, at / TRIALS, level, &top, best_mu, best_psi, best_q, evals)) return -2;
        /* inside its level set every point has mu >= level: a round that found nothing there stops, unproved */
        if (k && !(top > level - 0.5 * L->eps)) break;
        if (top > best) best = top;
        if (!isfinite(best)) break;
        before_level = level;
        level = fmax(best, 0.0) + L->eps;
        before = now;
        now = now == &buf[0] ? &buf[1] : &buf[0];
    }
    *level_out = level;
    return status;
}
