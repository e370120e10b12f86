/* Motions as piecewise polynomials: sampling one in place, and planning the quickest jerk-limited stop. */
#include <math.h>
#include <string.h>

#include "plem_core.h"

/* Knots closer than this (s) are one knot. */
#define KNOT_RESOLUTION 1e-9

/* The segment holding t: one step on from the last sample, a binary search otherwise. */
static int segment_of(plem_motion *m, double t) {
    const double *knots = m->knots;
    int s = m->cursor;
    if (s < 0 || s >= m->segments || t < knots[s] || (s + 2 <= m->segments && t >= knots[s + 2])) {
        int low = 0, high = m->segments;   /* the last knot <= t, within [0, segments - 1] */
        while (high - low > 1) {
            int middle = (low + high) / 2;
            if (knots[middle] <= t) low = middle;
            else high = middle;
        }
        s = low;
    } else if (t >= knots[s + 1] && s + 1 < m->segments) {
        s++;
    }
    m->cursor = s;
    return s;
}

int plem_motion_sample(plem_motion *m, double t, double *out) {
    int dof = m->dof;
    if (m->segments <= 0 || t >= m->knots[m->segments]) {
        memcpy(out, m->final, 3 * (size_t)dof * sizeof(double));
        return 1;
    }
    int s = segment_of(m, t);
    double tau = t > m->knots[s] ? t - m->knots[s] : 0.0;
    const double *c = m->coefficients + (size_t)s * PLEM_ORDER * (size_t)dof;
    for (int j = 0; j < dof; j++) {
        double p = 0.0, v = 0.0, a = 0.0;
        for (int k = PLEM_ORDER - 1; k >= 0; k--) {
            double ck = c[k * dof + j];
            p = p * tau + ck;
            if (k >= 1) v = v * tau + k * ck;
            if (k >= 2) a = a * tau + k * (k - 1) * ck;
        }
        out[j] = p, out[dof + j] = v, out[2 * dof + j] = a;
    }
    return 0;
}

/* One joint's stop: up to three phases, each starting at acceleration a0 (it may jump where jerk is unlimited)
 * and changing it at a constant jerk. */
typedef struct {
    int phases;
    double duration[3], a0[3], jerk[3];
} stop_phases;

static void add_phase(stop_phases *s, double duration, double a0, double jerk) {
    if (!(duration > 0.0)) return;
    s->duration[s->phases] = duration, s->a0[s->phases] = a0, s->jerk[s->phases] = jerk;
    s->phases++;
}

/* Time-optimal to v = a = 0 from (v0, a0) with |a| <= A, |jerk| <= J: ramp the acceleration toward the side that
 * brakes, hold it at the limit if needed, ramp it back to zero as the velocity reaches zero. */
static void joint_stop(double v0, double a0, double A, double J, stop_phases *s) {
    memset(s, 0, sizeof *s);
    double v_after = isinf(J) ? v0 : v0 + a0 * fabs(a0) / (2.0 * J);  /* velocity once a0 is ramped to zero */
    if (v_after == 0.0) {
        if (!isinf(J)) add_phase(s, fabs(a0) / J, a0, -copysign(J, a0));
        return;
    }
    double d = v_after < 0.0 ? 1.0 : -1.0, v = d * v0, a = d * a0;  /* now positive acceleration brakes */
    if (isinf(J)) {
        if (!isinf(A)) add_phase(s, -v / A, d * A, 0.0);   /* unlimited both ways: the joint stops at once */
        return;
    }
    double peak = sqrt(a * a / 2.0 - v * J), hold = 0.0;
    if (peak > A) {
        peak = fmax(A, a);
        hold = (-v - (2.0 * peak * peak - a * a) / (2.0 * J)) / peak;
    }
    add_phase(s, (peak - a) / J, d * a, d * J);
    add_phase(s, hold, d * peak, 0.0);
    add_phase(s, peak / J, d * peak, -d * J);
}

/* Advance (p, v, a) by t at constant jerk. */
static void advance(double *p, double *v, double *a, double jerk, double t) {
    *p += *v * t + *a * t * t / 2.0 + jerk * t * t * t / 6.0;
    *v += *a * t + jerk * t * t / 2.0;
    *a += jerk * t;
}

int plem_plan_stop(int dof, const double *p, const double *v, const double *a, const double *max_acceleration,
                   const double *max_jerk, double *knots, double *coefficients, double *final) {
    stop_phases stops[PLEM_MAX_JOINTS];
    double times[PLEM_STOP_SEGMENTS + 1];
    int count = 0;
    times[count++] = 0.0;
    for (int j = 0; j < dof; j++) {
        joint_stop(v[j], a[j], max_acceleration[j], max_jerk[j], &stops[j]);
        double t = 0.0, pj = p[j], vj = v[j], aj = a[j];
        for (int k = 0; k < stops[j].phases; k++) {
            aj = stops[j].a0[k];
            advance(&pj, &vj, &aj, stops[j].jerk[k], stops[j].duration[k]);
            times[count++] = t += stops[j].duration[k];
        }
        final[j] = pj, final[dof + j] = 0.0, final[2 * dof + j] = 0.0;
    }
    /* the knots: every phase boundary of every joint, sorted, those closer than the resolution merged */
    for (int i = 1; i < count; i++)
        for (int k = i; k > 0 && times[k] < times[k - 1]; k--) {
            double swap = times[k];
            times[k] = times[k - 1], times[k - 1] = swap;
        }
    int knots_count = 0;
    for (int i = 0; i < count; i++)
        if (knots_count == 0 || times[i] - knots[knots_count - 1] > KNOT_RESOLUTION) knots[knots_count++] = times[i];
    double end = times[count - 1];    /* the last knot is the end of the longest stop, however short */
    if (end > 0.0) knots_count == 1 ? (void)(knots[knots_count++] = end) : (void)(knots[knots_count - 1] = end);
    int segments = knots_count - 1;
    /* each segment starts every joint from its state there, at the jerk of the phase it is in */
    for (int j = 0; j < dof; j++) {
        double t = 0.0, pj = p[j], vj = v[j], aj = a[j];
        int phase = 0;
        for (int s = 0; s < segments; s++) {
            double start = knots[s], jerk = 0.0;
            while (phase < stops[j].phases && t + stops[j].duration[phase] <= start + KNOT_RESOLUTION) {
                aj = stops[j].a0[phase];
                advance(&pj, &vj, &aj, stops[j].jerk[phase], stops[j].duration[phase]);
                t += stops[j].duration[phase++];
            }
            if (phase < stops[j].phases) {
                double into = start - t;
                double ps = pj, vs = vj, as = stops[j].a0[phase];
                if (into > 0.0) advance(&ps, &vs, &as, stops[j].jerk[phase], into);
                else as = stops[j].a0[phase];
                jerk = stops[j].jerk[phase];
                double *c = coefficients + (size_t)s * PLEM_ORDER * (size_t)dof;
                c[j] = ps, c[dof + j] = vs, c[2 * dof + j] = as / 2.0, c[3 * dof + j] = jerk / 6.0;
            } else {
                double *c = coefficients + (size_t)s * PLEM_ORDER * (size_t)dof;
                c[j] = final[j], c[dof + j] = 0.0, c[2 * dof + j] = 0.0, c[3 * dof + j] = 0.0;
            }
            double *c = coefficients + (size_t)s * PLEM_ORDER * (size_t)dof;
            c[4 * dof + j] = c[5 * dof + j] = 0.0;
        }
    }
    return segments;
}
