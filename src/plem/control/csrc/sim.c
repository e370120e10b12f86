/* The simulated arm: CiA402 drives stepping on controlwords, encoders, and joints moved either as a rigid body
 * under the drives' servos (cyclic-sync position and velocity as a stiff PD evaluated at the cycle's end,
 * cyclic-sync torque as the commanded torque) or, without a model, as first-order followers of their targets.
 * Braked and jammed joints are locked in the dynamics; joints stop at their hard stops.
 */
#include <math.h>
#include <string.h>

#include "plem_core.h"

enum { FRICTION, SERVO, BIAS, WORK, PROBE, SOLVE, TARGET_Q, TARGET_V };

/* What each joint does this cycle, from its drive's state and mode. */
typedef struct {
    uint8_t running[PLEM_MAX_JOINTS], stopping[PLEM_MAX_JOINTS], position[PLEM_MAX_JOINTS];
    uint8_t velocity[PLEM_MAX_JOINTS], torque[PLEM_MAX_JOINTS], held[PLEM_MAX_JOINTS], commanded[PLEM_MAX_JOINTS];
    double position_gain[PLEM_MAX_JOINTS], velocity_gain[PLEM_MAX_JOINTS];
    int any_running, any_torque, any_held, servoed;
} joint_roles;

static void set_state(plem_sim *sim, int drive, int state) {
    sim->state[drive] = state;
    sim->statusword[drive] = plem_statusword_of(state);
}

static void roles_of(plem_sim *sim, joint_roles *r) {
    int n = sim->dof;
    double dt = sim->dt, omega = sim->omega;
    memset(r, 0, sizeof *r);
    for (int i = 0; i < n; i++) {
        int state = sim->state[i], mode = sim->io_mode[i];
        r->running[i] = state == PLEM_OPERATION_ENABLED || state == PLEM_QUICK_STOP_ACTIVE;
        r->stopping[i] = state == PLEM_QUICK_STOP_ACTIVE;
        int commanded = r->running[i] && !r->stopping[i];
        r->position[i] = r->stopping[i] || (commanded && mode == PLEM_CSP);
        r->velocity[i] = commanded && mode == PLEM_CSV;
        r->torque[i] = commanded && mode == PLEM_CST;
        r->held[i] = !(r->position[i] || r->velocity[i] || r->torque[i]) || sim->stuck[i]
                     || (!sim->dynamics && r->torque[i]);
        r->commanded[i] = (r->position[i] || r->velocity[i]) && !r->held[i];
        double kp = r->position[i] ? omega * omega : 0.0, kd = (r->position[i] || r->velocity[i]) ? 2.0 * omega : 0.0;
        double implicit = 1.0 + kd * dt + kp * dt * dt;
        r->position_gain[i] = kp / implicit;
        r->velocity_gain[i] = kd / implicit;
        if (r->held[i]) sim->v[i] = 0.0;
        if (r->stopping[i] && !sim->stopping[i]) sim->stop_q[i] = sim->q[i], sim->stop_v[i] = sim->v[i];
        sim->stopping[i] = r->stopping[i];
        if (!r->running[i]) sim->tau[i] = 0.0;  /* the brake holds, the drive applies nothing */
        r->any_running |= r->running[i];
        r->any_torque |= r->torque[i];
        r->any_held |= r->held[i];
        r->servoed |= r->commanded[i] || r->held[i];
    }
}

/* Commanded positions and velocities in SI; quick-stopping drives follow their own ramp. */
static void targets(plem_sim *sim, const joint_roles *r) {
    double *qd = sim->scratch[TARGET_Q], *vd = sim->scratch[TARGET_V];
    for (int i = 0; i < sim->dof; i++) {
        qd[i] = ((double)sim->io_target_position[i] - sim->raw_zero[i]) / sim->counts[i];
        vd[i] = (double)sim->io_velocity_offset[i] / sim->counts[i];
        if (!r->stopping[i]) continue;
        double speed = fabs(sim->stop_v[i]) - sim->deceleration * sim->dt;
        sim->stop_v[i] = copysign(speed > 0.0 ? speed : 0.0, sim->stop_v[i]);
        sim->stop_q[i] += sim->stop_v[i] * sim->dt;
        qd[i] = sim->stop_q[i];
        vd[i] = sim->stop_v[i];
    }
}

/* The drives' PD law at the cycle's end: (kp·(q_d − q − dt·v) + kd·(v_d − v)) / (1 + kd·dt + kp·dt²), the
 * position error capped so a large one drives the joint at its speed limit. */
static void servo_acceleration(const plem_sim *sim, const joint_roles *r, double *a) {
    const double *qd = sim->scratch[TARGET_Q], *vd = sim->scratch[TARGET_V];
    for (int i = 0; i < sim->dof; i++) {
        double error = qd[i] - sim->q[i] - sim->v[i] * sim->dt;
        error = fmin(fmax(error, -sim->max_error[i]), sim->max_error[i]);
        a[i] = r->held[i] ? 0.0 : error * r->position_gain[i] + (vd[i] - sim->v[i]) * r->velocity_gain[i];
    }
}

/* Scale the servoed accelerations down together until their torques fit the effort limits: torque is affine
 * in acceleration, so one factor keeps the motion's direction. */
static void fit_effort(plem_sim *sim, const joint_roles *r, double *tau) {
    double *bias = sim->scratch[BIAS], zero[PLEM_MAX_JOINTS] = {0}, scale = 1.0;
    int fits = 0;
    plem_inverse_dynamics(&sim->model, sim->q, sim->v, zero, bias);
    for (int i = 0; i < sim->dof; i++) {
        bias[i] += sim->scratch[FRICTION][i];
        double inertial = tau[i] - bias[i];
        if (!r->commanded[i] || !(fabs(bias[i]) < sim->effort[i]) || inertial == 0.0) continue;
        double bound = (copysign(sim->effort[i], inertial) - bias[i]) / inertial;
        scale = fits ? fmin(scale, bound) : fmin(1.0, bound);
        fits = 1;
    }
    if (!fits) return;
    for (int i = 0; i < sim->dof; i++) tau[i] = bias[i] + scale * (tau[i] - bias[i]);
}

/* Solve A x = b in place (A n×n row-major, partial pivoting); A is small and, for locks, well conditioned. */
static void solve(int n, double A[][PLEM_MAX_JOINTS], double *b) {
    for (int c = 0; c < n; c++) {
        int pivot = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(A[r][c]) > fabs(A[pivot][c])) pivot = r;
        if (pivot != c) {
            for (int k = 0; k < n; k++) {
                double t = A[c][k];
                A[c][k] = A[pivot][k], A[pivot][k] = t;
            }
            double t = b[c];
            b[c] = b[pivot], b[pivot] = t;
        }
        for (int r = c + 1; r < n; r++) {
            double f = A[r][c] / A[c][c];
            for (int k = c; k < n; k++) A[r][k] -= f * A[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int c = n - 1; c >= 0; c--) {
        for (int k = c + 1; k < n; k++) b[c] -= A[c][k] * b[k];
        b[c] /= A[c][c];
    }
}

/* Free-arm accelerations → those with the braked or jammed joints locked: the locks add torques λ on the held
 * joints so their accelerations vanish; accelerations are affine in λ with the columns of M⁻¹. */
static void lock_held(plem_sim *sim, const joint_roles *r, const double *torque, double *a) {
    int n = sim->dof, held[PLEM_MAX_JOINTS], count = 0;
    double columns[PLEM_MAX_JOINTS][PLEM_MAX_JOINTS], A[PLEM_MAX_JOINTS][PLEM_MAX_JOINTS], x[PLEM_MAX_JOINTS];
    double *probe = sim->scratch[PROBE];
    for (int i = 0; i < n; i++)
        if (r->held[i]) held[count++] = i;
    for (int row = 0; row < count; row++) {
        memcpy(probe, torque, (size_t)n * sizeof(double));
        probe[held[row]] += 1.0;
        plem_forward_dynamics(&sim->model, sim->q, sim->v, probe, columns[row]);
        for (int i = 0; i < n; i++) columns[row][i] -= a[i];
    }
    for (int i = 0; i < count; i++) {
        for (int row = 0; row < count; row++) A[i][row] = columns[row][held[i]];
        x[i] = -a[held[i]];
    }
    solve(count, A, x);
    for (int row = 0; row < count; row++)
        for (int i = 0; i < n; i++) a[i] += columns[row][i] * x[row];
    for (int i = 0; i < count; i++) a[held[i]] = 0.0;
}

static void hard_stop(plem_sim *sim) {
    for (int i = 0; i < sim->dof; i++) {
        if (sim->q[i] > sim->upper[i]) sim->q[i] = sim->upper[i], sim->v[i] = 0.0;
        else if (sim->q[i] < sim->lower[i]) sim->q[i] = sim->lower[i], sim->v[i] = 0.0;
    }
}

/* When every joint is servoed within its effort limit and nothing pushes, the torque is the inverse dynamics of the
 * servo's acceleration, so forward dynamics would only give that acceleration back: it is skipped then. */
static void step_dynamics(plem_sim *sim, const joint_roles *r) {
    int n = sim->dof, clamp = r->any_torque, pushed = 0, servo_only = 0;
    double *friction = sim->scratch[FRICTION], *a = sim->scratch[SERVO], *work = sim->scratch[WORK], *tau = sim->tau;
    double push[PLEM_MAX_JOINTS] = {0};
    targets(sim, r);
    if (sim->push_body >= 0 && sim->push_body < n)   /* a wrench on a link, as joint torques at this pose */
        plem_wrench_torques(&sim->model, sim->q, sim->push_body, sim->push_point, sim->push, push);
    for (int i = 0; i < n; i++) {
        friction[i] = sim->v[i] * sim->friction[i];
        push[i] += sim->external[i];
        pushed |= push[i] != 0.0;
    }
    if (r->servoed) {
        int saturated = 0;
        servo_acceleration(sim, r, a);
        plem_inverse_dynamics(&sim->model, sim->q, sim->v, a, tau);
        for (int i = 0; i < n; i++) {
            tau[i] += friction[i];
            saturated |= fabs(tau[i]) > sim->effort[i];
        }
        if (saturated) {
            fit_effort(sim, r, tau);
            clamp = 1;
        }
        servo_only = !saturated && !r->any_torque && !r->any_held && !pushed;
    }
    for (int i = 0; i < n; i++) {
        if (r->torque[i]) tau[i] = sim->io_torque_offset[i];
        if (clamp) tau[i] = fmax(fmin(tau[i], sim->effort[i]), -sim->effort[i]);
        if (!r->running[i]) tau[i] = 0.0;
        work[i] = tau[i] - friction[i] + push[i];
    }
    if (!servo_only) plem_forward_dynamics(&sim->model, sim->q, sim->v, work, a);
    if (r->any_held) lock_held(sim, r, work, a);
    for (int i = 0; i < n; i++) {
        sim->v[i] += a[i] * sim->dt;
        sim->q[i] += sim->v[i] * sim->dt;
    }
    hard_stop(sim);
}

static void step_follower(plem_sim *sim, const joint_roles *r) {
    const double *qd = sim->scratch[TARGET_Q], *vd = sim->scratch[TARGET_V];
    targets(sim, r);
    for (int i = 0; i < sim->dof; i++) {
        double next = (sim->q[i] - qd[i]) * sim->follow + qd[i];
        if (r->velocity[i]) next = sim->q[i] + vd[i] * sim->dt;
        if (r->held[i]) next = sim->q[i];
        sim->v[i] = (next - sim->q[i]) / sim->dt;
        sim->q[i] = next;
    }
}

/* One cycle under the drives' current states and modes; nothing moves while every drive is off. A payload written
 * since the last cycle is mounted first: the last body's inertials become it. */
static void advance(plem_sim *sim) {
    if (sim->payload_pending) {
        int last = sim->model.dof - 1;
        sim->model.mass[last] = sim->payload_body[0];
        memcpy(sim->model.com[last], sim->payload_body + 1, sizeof sim->model.com[last]);
        memcpy(sim->model.inertia[last], sim->payload_body + 4, sizeof sim->model.inertia[last]);
        sim->payload_pending = 0;
    }
    joint_roles roles;
    roles_of(sim, &roles);
    if (!roles.any_running) return;
    if (sim->dynamics) step_dynamics(sim, &roles);
    else step_follower(sim, &roles);
}

/* The drives' side of one cycle: each takes its controlword; a latched fault stays. */
static void apply(plem_sim *sim, const uint16_t *commands) {
    for (int i = 0; i < sim->dof; i++) {
        uint16_t previous = sim->controlword[i];
        int state = sim->state[i], next = plem_drive_transition(state, commands[i], previous);
        sim->controlword[i] = commands[i];
        if (state == PLEM_FAULT && next != state) {
            if (sim->latched[i]) next = state;
            else sim->error_code[i] = 0;
        }
        if (next != state) set_state(sim, i, next);
    }
}

int plem_sim_read(plem_sim *sim) {
    if (sim->lost && sim->lost_reads != 0) {
        if (sim->lost_reads > 0) sim->lost_reads--;
        sim->lost_frames++;
        sim->answered = 0;
        plem_power_master_lost(&sim->power);
        return 0;
    }
    sim->answered = 1;
    sim->lost = 0;
    sim->lost_reads = -1;
    for (int i = 0; i < sim->dof; i++) {
        sim->io_position[i] = (int64_t)rint(sim->q[i] * sim->counts[i] + sim->raw_zero[i]) + sim->spike[i];
        sim->spike[i] = 0;
        sim->io_velocity[i] = (int64_t)rint(sim->v[i] * sim->counts[i]);
        sim->io_torque[i] = sim->tau[i];
        sim->io_statusword[i] = sim->statusword[i];
        sim->io_error_code[i] = sim->error_code[i];
    }
    return 1;
}

void plem_sim_exchange(plem_sim *sim, const uint16_t *controlwords) {
    if (sim->lost) plem_sim_quick_stop(sim);
    else apply(sim, controlwords);
    advance(sim);
}

void plem_sim_write(plem_sim *sim) {
    int32_t seen[PLEM_MAX_JOINTS];
    uint16_t commands[PLEM_MAX_JOINTS] = {0};
    if (!sim->lost) {
        for (int i = 0; i < sim->dof; i++) seen[i] = plem_decode_statusword(sim->io_statusword[i]);
        plem_power_commands(&sim->power, seen, commands);
    }
    plem_sim_exchange(sim, commands);
}

void plem_sim_serve(plem_sim *sim, const uint16_t *controlwords) {
    apply(sim, controlwords);
    advance(sim);
}

int plem_sim_quick_stop(plem_sim *sim) {
    int changed = 0;
    for (int i = 0; i < sim->dof; i++)
        if (sim->state[i] == PLEM_OPERATION_ENABLED) set_state(sim, i, PLEM_QUICK_STOP_ACTIVE), changed = 1;
    return changed;
}

void plem_sim_fault(plem_sim *sim, int drive, uint16_t error_code, int latched) {
    set_state(sim, drive, PLEM_FAULT);
    sim->error_code[drive] = error_code;
    sim->latched[drive] = (uint8_t)(latched != 0);
}

void plem_sim_power_off(plem_sim *sim) {
    for (int i = 0; i < sim->dof; i++)
        if (sim->state[i] != PLEM_FAULT) set_state(sim, i, PLEM_SWITCH_ON_DISABLED);
    plem_power_request(&sim->power, PLEM_SWITCH_ON_DISABLED);
}
