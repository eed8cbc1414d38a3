/* One step of the planner's dynamic programming (qpik.planning.dp, _Step.banded): the best banded
 * transition into every state of waypoint k + 1.
 *
 * States are (branch row b, grid index j), B x G, configurations of n joints, row-major. For each
 * feasible destination (b, j) the sources are (b, (j - o) mod G) for the O offsets o; a source
 * counts when its value is finite, every joint moves by at most lim[.] and, with vel, the velocity
 * change (D / dt - vel[source]) stays within dv[.] on every joint. Among the sources, the one with
 * the fewest jumps J, then the least V + wm |D|^2, is kept; the destination's value adds wp f[b, j].
 * Destinations with no source get V = inf, J = 0, src = -1.
 */
#include <math.h>

void qpik_dp_banded(long long B, long long G, long long n, long long O, const long long *offsets,
                    const double *qa, const double *qb, const unsigned char *okb, const double *fb,
                    const double *V, const long long *J, const double *lim, double wm, double wp,
                    const double *vel, double inv_dt, const double *dv, double *Vn, long long *Jn,
                    long long *src) {
    for (long long b = 0; b < B; ++b) {
        for (long long j = 0; j < G; ++j) {
            long long d = b * G + j, best = -1, best_J = 0;
            double best_V = INFINITY;
            if (okb[d]) {
                const double *y = qb + d * n;
                for (long long t = 0; t < O; ++t) {
                    long long i = j - offsets[t]; /* offsets lie in (-G, G): one turn at most */
                    i += i < 0 ? G : (i >= G ? -G : 0);
                    long long s = b * G + i;
                    if (!isfinite(V[s]) || (best >= 0 && J[s] > best_J)) continue;
                    const double *x = qa + s * n;
                    double sq = 0.0;
                    int fits = 1;
                    for (long long m = 0; m < n && fits; ++m) {
                        double step = y[m] - x[m];
                        fits = fabs(step) <= lim[m];
                        if (vel) fits = fits && fabs(step * inv_dt - vel[s * n + m]) <= dv[m];
                        sq += step * step;
                    }
                    if (!fits) continue;
                    double c = V[s] + wm * sq;
                    if (best < 0 || J[s] < best_J || c < best_V) best = s, best_J = J[s], best_V = c;
                }
            }
            Vn[d] = best >= 0 ? best_V + wp * fb[d] : INFINITY;
            Jn[d] = best >= 0 ? best_J : 0;
            src[d] = best;
        }
    }
}
