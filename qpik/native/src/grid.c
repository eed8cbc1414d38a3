/* The planner's grid states (qpik.planning.grid, Grid.layers) in one loop over the CasADi-generated row
 * function, split at its waypoint-only part (Grid.split_function; both called through their C entry points).
 *
 * pre(c) -> s runs once per waypoint and row(c, s, parameter) per grid value, c = [pose, the other fixed
 * inputs] (fixed; its first 16 entries, the pose, are written here). The row gives, per gridded branch b,
 * [q (n), valid and within the limits, f(q), smallest clearance (m)]; the clearance of branch b at grid index i is root[b]'s at index
 * (i + shift[b]) mod G (Grid.clearance_sources). For waypoints k = 0..K-1 (poses column-major, 16 entries
 * each) the row function is evaluated at the grid values where some branch is inside its exact feasible
 * set (inside[k, b, i]) or whose clearance such a branch needs, and the outputs go straight to their
 * places, states (k, b, i) row-major: q[k, b, i, :], ok[k, b, i] = inside and valid and within the limits
 * and clearance >= d_safe and f finite, f[k, b, i] (inf where not ok). Rows not evaluated: q = 0, ok = 0,
 * f = inf. clear (B x G) and need (G) are scratch. Returns 0, or -1 when a generated function fails.
 */
#include <math.h>
#include <string.h>

#include "casadi_call.h"

int qpik_plan_layers(void *pre, const double **pre_arg, double **pre_res, casadi_int *pre_iw, double *pre_w,
                     void *fn, const double **arg, double **res, casadi_int *iw, double *w, double *fixed,
                     double *param, const double *row, long long K, long long B, long long G, long long n,
                     const double *cols, const double *values, const unsigned char *inside, const long long *root,
                     const long long *shift, double d_safe, double *clear, unsigned char *need, double *q,
                     unsigned char *ok, double *f) {
    casadi_fn call = (casadi_fn)fn, prepare = (casadi_fn)pre;
    for (long long k = 0; k < K; ++k) {
        memcpy(fixed, cols + 16 * k, 16 * sizeof(double));
        if (prepare(pre_arg, pre_res, pre_iw, pre_w, 0)) return -1;
        const unsigned char *in = inside + k * B * G;
        memset(need, 0, (size_t)G);
        for (long long b = 0; b < B; ++b)
            for (long long i = 0; i < G; ++i)
                if (in[b * G + i]) need[i] = need[(i + shift[b]) % G] = 1;
        for (long long i = 0; i < G; ++i) {
            if (need[i]) {
                *param = values[i];
                if (call(arg, res, iw, w, 0)) return -1;
            }
            for (long long b = 0; b < B; ++b) {
                long long s = (k * B + b) * G + i;
                const double *r = row + b * (n + 3);
                if (need[i]) {
                    memcpy(q + s * n, r, (size_t)n * sizeof(double));
                    ok[s] = r[n] > 0.5, f[s] = r[n + 1], clear[b * G + i] = r[n + 2];
                } else {
                    memset(q + s * n, 0, (size_t)n * sizeof(double));
                    ok[s] = 0, f[s] = INFINITY, clear[b * G + i] = NAN;
                }
            }
        }
        for (long long b = 0; b < B; ++b) {
            for (long long i = 0; i < G; ++i) {
                long long s = (k * B + b) * G + i;
                double d = clear[root[b] * G + (i + shift[b]) % G];
                int good = in[b * G + i] && ok[s] && d >= d_safe && isfinite(f[s]);
                ok[s] = (unsigned char)good;
                if (!good) f[s] = INFINITY;
            }
        }
    }
    return 0;
}
