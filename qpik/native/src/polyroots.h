/* Real roots of A(cos delta) + sin delta B(cos delta) (polyroots.c), for the C files that solve the wrist equations
 * (offset_shoulder_intervals.c). */
#ifndef QPIK_POLYROOTS_H
#define QPIK_POLYROOTS_H

/* The roots delta in [-pi, pi] of the K rows of coefficients A and B (K x (na + 1) each, row-major, lowest degree
 * first), at most `room` of them: delta[i] and the row owner[i] of each, rows ascending. Returns how many, or -1 when
 * a row's degree is above the root finder's or the room is too small. */
int qpik_trig_roots(int K, int na, const double *A, const double *B, int room, double *delta, int *owner);

#endif
