/* An online jerk-limited follower: each cycle, each joint's command moves toward a target position or velocity as
 * fast as its velocity, acceleration and jerk limits allow, and stops before its position limits.
 *
 * Two nested laws. The wanted velocity is the target's own plus the speed from which the joint can still brake to
 * the target (at BRAKE of its acceleration limit, so the inner law has room to catch up), and near the target a
 * first-order approach over SETTLE cycles. The acceleration then brings the velocity to the wanted one: the
 * acceleration for the coming cycle is the one from which a jerk-limited ramp back to zero acceleration lands on
 * it, computed for the cycle's own trapezoidal integration, so it settles in two cycles instead of buzzing.
 *
 * The joints are independent; each law is one short loop over them, so the processor works on several joints at
 * once instead of waiting on one joint's chain of roots and divisions.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "plem_core.h"

/* Share of the acceleration limit the position laws plan their braking with. */
#define BRAKE 0.5
/* Cycles over which the last stretch to a target position is closed. */
#define SETTLE 10.0

/* The cube root of x > 0, to within a few parts in 10^15: an exponent-thirding guess (within 4 %) and two Halley
 * steps, each tripling the correct digits. libm's cbrt is a call the processor cannot overlap with the other
 * joints' work (measured for 6 joints: 150 ns a cycle with it, 110 with this). */
static double cube_root(double x) {
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    bits = bits / 3 + 0x2A9F7893782DA1CEULL;
    double y;
    memcpy(&y, &bits, sizeof y);
    for (int step = 0; step < 2; step++) {
        double cube = y * y * y;
        y = y * (cube + 2.0 * x) / (2.0 * cube + x);
    }
    return y;
}

/* The highest speed from which a stop at acceleration A and jerk J, starting at zero acceleration, ends within d. */
static double braking_speed(double d, double A, double J) {
    if (!(d > 0.0)) return 0.0;
    if (isinf(J)) return isinf(A) ? INFINITY : sqrt(2.0 * A * d);
    if (isinf(A) || d <= A * A * A / (J * J)) return cube_root(d * d * J);   /* the acceleration never saturates */
    return -A * A / (2.0 * J) + sqrt(A * A * A * A / (4.0 * J * J) + 2.0 * A * d);
}

/* The velocity gained is (a + x)·dt/2 this cycle and max(|x|·dt/2, x²/2J) ramping x back to zero afterwards. */
double plem_approach(double v, double a, double goal, double A, double J, double dt) {
    double rest = goal - v - a * dt / 2.0, x;
    if (!(fabs(rest) > J * dt * dt)) x = rest / dt;
    else x = copysign(J * (sqrt(dt * dt / 4.0 + 2.0 * fabs(rest) / J) - dt / 2.0), rest);
    return plem_clamp(plem_clamp(x, a - J * dt, a + J * dt), -A, A);
}

void plem_follow(int n, double *p, double *v, double *a, const plem_follow_targets *t, double dt) {
    double ahead[PLEM_MAX_JOINTS], goal[PLEM_MAX_JOINTS], A[PLEM_MAX_JOINTS], J[PLEM_MAX_JOINTS];
    /* where each joint is once its acceleration is ramped back to zero: the velocity laws act from there */
    for (int i = 0; i < n; i++) {
        A[i] = t->max_acceleration[i] * t->share, J[i] = t->max_jerk[i] * t->share;
        double ramp = isinf(J[i]) ? 0.0 : fabs(a[i]) / J[i];
        double velocity = t->target_velocity ? t->target_velocity[i] : 0.0;
        ahead[i] = p[i] + v[i] * ramp + a[i] * ramp * ramp / 2.0 - copysign(J[i], a[i]) * ramp * ramp * ramp / 6.0;
        goal[i] = velocity;
        if (t->target_position) {
            double error = plem_clamp(t->target_position[i] + velocity * ramp, t->low[i], t->high[i]) - ahead[i];
            double toward = plem_lesser(braking_speed(fabs(error), BRAKE * A[i], BRAKE * J[i]),
                                        fabs(error) / (SETTLE * dt));
            goal[i] = velocity + copysign(toward, error);
        }
    }
    /* a limit closer than a stop from the wanted speed takes: brake for it (farther, it cannot bind) */
    for (int i = 0; i < n; i++) {
        double speed = t->max_velocity[i] * t->share * t->speed;
        double wanted = plem_clamp(goal[i], -speed, speed), w = fabs(wanted);
        double a_brake = BRAKE * A[i], j_brake = BRAKE * J[i];
        double stop = w * w / (2.0 * a_brake);
        if (!isinf(j_brake)) stop = stop + w * a_brake / (2.0 * j_brake) + w * sqrt(w / j_brake);
        double high = t->high[i] - ahead[i], low = ahead[i] - t->low[i];
        if (wanted > 0.0 && high < stop) wanted = plem_lesser(wanted, braking_speed(high, a_brake, j_brake));
        if (wanted < 0.0 && low < stop) wanted = plem_greater(wanted, -braking_speed(low, a_brake, j_brake));
        goal[i] = wanted;
    }
    for (int i = 0; i < n; i++) {
        double next = plem_approach(v[i], a[i], goal[i], A[i], J[i], dt), limit = t->max_velocity[i] * t->share;
        double velocity = plem_clamp(v[i] + (a[i] + next) * dt / 2.0, -limit, limit);
        double position = p[i] + (v[i] + velocity) * dt / 2.0 + (a[i] - next) * dt * dt / 12.0;
        p[i] = plem_clamp(position, plem_lesser(t->low[i], p[i]), plem_greater(t->high[i], p[i]));
        v[i] = velocity;
        a[i] = next;
    }
}
