/* An online jerk-limited follower: each cycle, one joint's command moves toward a target position or velocity as
 * fast as its velocity, acceleration and jerk limits allow, and stops before its position limits.
 *
 * Two nested laws. The wanted velocity is the target's own plus the speed from which the joint can still brake to
 * the target (at BRAKE of its acceleration limit, so the inner law has room to catch up), and near the target a
 * first-order approach over SETTLE cycles. The acceleration then brings the velocity to the wanted one: the
 * acceleration for the coming cycle is the one from which a jerk-limited ramp back to zero acceleration lands on
 * it, computed for the cycle's own trapezoidal integration, so it settles in two cycles instead of buzzing.
 */
#include <math.h>

#include "plem_core.h"

/* Share of the acceleration limit the position laws plan their braking with. */
#define BRAKE 0.5
/* Cycles over which the last stretch to a target position is closed. */
#define SETTLE 10.0

/* fmin and fmax without their NaN rules, which keep the compiler from inlining them (a call each, in a loop over
 * the joints every cycle); a NaN x still clamps to `low`, as fmax gives. */
static double lesser(double a, double b) { return a < b ? a : b; }
static double greater(double a, double b) { return a > b ? a : b; }
static double clamp(double x, double low, double high) { return lesser(greater(x, low), high); }

/* The highest speed from which a stop at acceleration A and jerk J, starting at zero acceleration, ends within d. */
static double braking_speed(double d, double A, double J) {
    if (!(d > 0.0)) return 0.0;
    if (isinf(J)) return isinf(A) ? INFINITY : sqrt(2.0 * A * d);
    if (isinf(A) || d <= A * A * A / (J * J)) return cbrt(d * d * J);   /* the acceleration never saturates */
    return -A * A / (2.0 * J) + sqrt(A * A * A * A / (4.0 * J * J) + 2.0 * A * d);
}

/* The velocity gained is (a + x)·dt/2 this cycle and max(|x|·dt/2, x²/2J) ramping x back to zero afterwards. */
double plem_approach(double v, double a, double goal, double A, double J, double dt) {
    double rest = goal - v - a * dt / 2.0, x;
    if (!(fabs(rest) > J * dt * dt)) x = rest / dt;
    else x = copysign(J * (sqrt(dt * dt / 4.0 + 2.0 * fabs(rest) / J) - dt / 2.0), rest);
    return clamp(clamp(x, a - J * dt, a + J * dt), -A, A);
}

void plem_follow(double *p, double *v, double *a, double target_position, double target_velocity, double speed,
                 double max_velocity, double max_acceleration, double max_jerk, double low, double high, double dt) {
    double A = max_acceleration, J = max_jerk, goal = target_velocity;
    /* where the joint is once its acceleration is ramped back to zero: the velocity laws act from there */
    double ramp = isinf(J) ? 0.0 : fabs(*a) / J;
    double ahead = *p + *v * ramp + *a * ramp * ramp / 2.0 - copysign(J, *a) * ramp * ramp * ramp / 6.0;
    if (isfinite(target_position)) {
        double error = clamp(target_position + target_velocity * ramp, low, high) - ahead;
        double toward = lesser(braking_speed(fabs(error), BRAKE * A, BRAKE * J), fabs(error) / (SETTLE * dt));
        goal = target_velocity + copysign(toward, error);
    }
    goal = clamp(goal, -speed, speed);
    /* a limit closer than a stop from the wanted speed takes: brake for it (farther, it cannot bind) */
    double a_brake = BRAKE * A, j_brake = BRAKE * J, w = fabs(goal);
    double stop = isinf(j_brake) ? w * w / (2.0 * a_brake) : w * w / (2.0 * a_brake) + w * a_brake / (2.0 * j_brake)
                                                             + w * sqrt(w / j_brake);
    if (goal > 0.0 && high - ahead < stop) goal = lesser(goal, braking_speed(high - ahead, a_brake, j_brake));
    if (goal < 0.0 && ahead - low < stop) goal = greater(goal, -braking_speed(ahead - low, a_brake, j_brake));
    double next = plem_approach(*v, *a, goal, A, J, dt);
    double velocity = clamp(*v + (*a + next) * dt / 2.0, -max_velocity, max_velocity);
    double position = *p + (*v + velocity) * dt / 2.0 + (*a - next) * dt * dt / 12.0;
    *p = clamp(position, lesser(low, *p), greater(high, *p));
    *v = velocity;
    *a = next;
}
