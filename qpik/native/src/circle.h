/* Angles on the circle: pi, 2 pi and the wrap to (-pi, pi] (qpik.analytic.intervals.wrap). */
#ifndef QPIK_CIRCLE_H
#define QPIK_CIRCLE_H

#include <math.h>

#define PI 3.141592653589793
#define TWO_PI 6.283185307179586

/* As qpik.algebra.symbolic.Ops.wrap: x + 2 pi floor((pi - x) / 2 pi), in (-pi, pi]. */
static inline double wrap(double x) { return x + TWO_PI * floor((PI - x) / TWO_PI); }

#endif
