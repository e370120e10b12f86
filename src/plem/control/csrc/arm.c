/* One arm's cycle: read the bus, supervise what it measures, take requests, run the mode's controller, check the
 * command against every limit, write the bus, publish. Everything a person reads about it (fault reasons, refusals)
 * leaves as codes and numbers on the event and outcome rings; Python words them.
 */
#include <math.h>
#include <stdatomic.h>
#include <string.h>

#include "clock.h"
#include "plem_core.h"

/* Rare work (requests, events, faults, firing reactions): kept out of the path every cycle runs, so that path
 * stays compact in the instruction cache the 1 ms sleep leaves cold. */
#define COLD __attribute__((cold))

#define ENABLED_MASK 0x006F
#define ENABLED_VALUE 0x0027
#define STATUS_FAULT_BIT 0x0008
/* A goal time tolerance beyond this many cycles (or infinite) waits this long: about 3 years at 1 kHz. */
#define MAX_SETTLE_CYCLES (1LL << 47)
/* Stops are planned this far inside the limits, as every other motion is. */
#define INSIDE (1.0 - 1e-6)
#define POSITION 0
#define VELOCITY 1
#define EFFORT 2
#define COMMAND 3
/* The speed override: how fast the factor follows its target (1/s) at most, and its rate's change (1/s²) when no
 * motion bounds it; the share of a joint's acceleration room its rate may take. */
#define OVERRIDE_RATE 2.0
#define OVERRIDE_RATE_CHANGE 20.0
#define OVERRIDE_SHARE 0.9

/* The motion slab's layout (plem.ipc.motion_slab): a 64-byte header, then per slot its segment count, final state,
 * knots and coefficients as float64. */
#define SLAB_HEADER_BYTES 64
typedef struct { char magic[8]; uint32_t version, dof, slots, capacity, shared_slots; } slab_header;

/* ---- rings ---------------------------------------------------------------------------------------------- */

/* The next free record of a ring the core produces into, or NULL (counted as dropped) when the reader is behind. */
static void *produce(plem_ring *ring, void *records, size_t size, uint64_t slots) {
    uint64_t head = ring->head, tail = atomic_load_explicit((_Atomic uint64_t *)&ring->tail, memory_order_acquire);
    if (head - tail >= slots) {
        ring->dropped++;
        return NULL;
    }
    void *record = (uint8_t *)records + (head % slots) * size;
    memset(record, 0, size);
    return record;
}

static void publish_record(plem_ring *ring) {
    atomic_store_explicit((_Atomic uint64_t *)&ring->head, ring->head + 1, memory_order_release);
}

COLD static void emit(plem_arm *arm, int kind, int cause, int previous, int joint, int detail, uint64_t token,
                      double v0, double v1, double v2, double v3) {
    plem_event *event = produce(&arm->events_index, arm->events, sizeof(plem_event), PLEM_EVENT_SLOTS);
    if (!event) return;
    event->cycle = arm->cycle, event->monotonic_ns = plem_now_ns(), event->token = token;
    event->kind = kind, event->cause = cause, event->mode = arm->mode, event->previous_mode = previous;
    event->joint = joint, event->detail = detail;
    event->values[0] = v0, event->values[1] = v1, event->values[2] = v2, event->values[3] = v3;
    publish_record(&arm->events_index);
}

COLD static void answer(plem_arm *arm, uint64_t token, int stage, int code, int mode, int detail, int joint,
                        double v0, double v1) {
    plem_outcome *outcome = produce(&arm->outcomes_index, arm->outcomes, sizeof(plem_outcome), PLEM_OUTCOME_SLOTS);
    if (!outcome) return;
    outcome->token = token, outcome->cycle = arm->cycle, outcome->stage = stage, outcome->answer = code;
    outcome->mode = mode, outcome->detail = detail, outcome->joint = joint;
    outcome->values[0] = v0, outcome->values[1] = v1;
    publish_record(&arm->outcomes_index);
}

static void reject(plem_arm *arm, uint64_t token, int code, int detail, int joint, double v0, double v1) {
    answer(arm, token, PLEM_REJECTED, code, arm->mode, detail, joint, v0, v1);
}

/* ---- small pieces --------------------------------------------------------------------------------------- */

static double *row(plem_arm *arm, int r) { return arm->work[r]; }

static int drive_enabled(const plem_arm *arm, int i) {
    return (arm->io_statusword[i] & ENABLED_MASK) == ENABLED_VALUE;
}

/* Whether commands reach any drive (a faulted drive ignores its share and holds on its brake). */
static int can_command(const plem_arm *arm) {
    if (!arm->communication_ok) return 0;
    for (int i = 0; i < arm->settings.dof; i++)
        if (drive_enabled(arm, i)) return 1;
    return 0;
}

static void request_power(plem_arm *arm, int state) {
    arm->power_wanted = state;
    arm->power_requests++;
    plem_power_request(&arm->power, state);
}

static void set_io_mode(plem_arm *arm, int mode) {
    for (int i = 0; i < arm->settings.dof; i++) arm->io_mode[i] = (int8_t)mode;
}

/* The position range commands may use from now on: each joint's limits, widened to include where the command is
 * (a joint outside its range may move back toward it, never farther out). */
static void reach_from_command(plem_arm *arm) {
    const plem_settings *s = &arm->settings;
    for (int i = 0; i < s->dof; i++) {
        arm->reach[0][i] = fmin(s->min_position[i], row(arm, COMMAND)[i]);
        arm->reach[1][i] = fmax(s->max_position[i], row(arm, COMMAND)[i]);
    }
}

/* The command where the arm is, at rest. */
static void seed_from_measurement(plem_arm *arm) {
    int n = arm->settings.dof;
    memcpy(row(arm, COMMAND), row(arm, POSITION), (size_t)n * sizeof(double));
    memset(row(arm, COMMAND + 1), 0, (size_t)n * sizeof(double));
    memset(row(arm, COMMAND + 2), 0, (size_t)n * sizeof(double));
    reach_from_command(arm);
}

/* The command where the arm is and how it moves (free drive: the arm leads, the command follows). */
static void follow_measurement(plem_arm *arm) {
    int n = arm->settings.dof;
    memcpy(row(arm, COMMAND), row(arm, POSITION), (size_t)n * sizeof(double));
    memcpy(row(arm, COMMAND + 1), row(arm, VELOCITY), (size_t)n * sizeof(double));
    memset(row(arm, COMMAND + 2), 0, (size_t)n * sizeof(double));
}

static void leave_free_drive(plem_arm *arm) {
    set_io_mode(arm, PLEM_CSP);
    follow_measurement(arm);
    memset(arm->previous_acceleration, 0, sizeof arm->previous_acceleration);
}

static void set_mode(plem_arm *arm, int mode, int cause, uint64_t token, int detail) {
    if (mode == arm->mode) return;
    int previous = arm->mode;
    arm->mode = mode;
    emit(arm, PLEM_EVENT_MODE_CHANGED, cause, previous, -1, detail, token, 0, 0, 0, 0);
}

/* Centre and half-width of the range joint i may use (`reach`): an unlimited joint has centre 0 and half-width inf. */
static void range_of(const plem_arm *arm, int i, double *center, double *half) {
    double low = arm->reach[0][i], high = arm->reach[1][i];
    if (isfinite(low) && isfinite(high)) {
        *center = (low + high) / 2.0;
        *half = (high - low) / 2.0;
    } else {
        *center = 0.0, *half = INFINITY;
    }
}

/* ---- motions -------------------------------------------------------------------------------------------- */

/* The start of slot `slot` of the slab as float64, or NULL when the slab does not have it. */
static const double *slab_slot(const plem_slab *slab, int dof, int slot, int32_t *capacity) {
    if (!slab || !slab->base || slab->size < SLAB_HEADER_BYTES) return NULL;
    slab_header header;
    memcpy(&header, slab->base, sizeof header);
    if (memcmp(header.magic, "PLEMMOTN", 8) != 0 || header.version != 2 || (int)header.dof != dof || slot < 0
        || (uint32_t)slot >= header.slots)
        return NULL;
    int64_t values = 1 + 3 * (int64_t)dof + (header.capacity + 1) + (int64_t)header.capacity * PLEM_ORDER * dof;
    if (SLAB_HEADER_BYTES + (int64_t)header.slots * values * 8 > slab->size) return NULL;
    *capacity = (int32_t)header.capacity;
    return (const double *)(slab->base + SLAB_HEADER_BYTES) + (int64_t)slot * values;
}

/* The running motion as the sampler sees it. */
static int active_motion(plem_arm *arm, const plem_slab *slab, plem_motion *motion) {
    int dof = arm->settings.dof;
    motion->dof = dof, motion->segments = arm->active_segments, motion->cursor = arm->active_cursor;
    if (arm->active_slot == PLEM_STOP_SLOT) {
        motion->knots = arm->stop_knots, motion->coefficients = arm->stop_coefficients;
        motion->final = arm->stop_final;
        return 1;
    }
    int32_t capacity;
    const double *values = slab_slot(slab, dof, arm->active_slot, &capacity);
    if (!values) return 0;
    motion->final = values + 1;
    motion->knots = values + 1 + 3 * dof;
    motion->coefficients = values + 2 + 3 * dof + capacity;
    return 1;
}

/* A slot's condition is a whole postfix program over quantities the arm has: every term known, every index within
 * its measure, every combination with its operands, one truth at the end. */
static int well_formed(const plem_arm *arm, const plem_reaction *r) {
    int n = arm->settings.dof, depth = 0;
    if (r->terms < 1 || r->terms > PLEM_REACTION_TERMS) return 0;
    for (int k = 0; k < r->terms; k++) {
        const plem_term *t = &r->term[k];
        int i = t->index;
        switch (t->op) {
        case PLEM_TERM_AND:
        case PLEM_TERM_OR:
            if (depth-- < 2) return 0;
            break;
        case PLEM_TERM_NOT:
            if (depth < 1) return 0;
            break;
        case PLEM_TERM_ABOVE:
        case PLEM_TERM_BELOW:
        case PLEM_TERM_EQUAL: {
            int limit = t->measure == PLEM_MEASURE_WRENCH ? 6 : t->measure == PLEM_MEASURE_MOTION_TIME ? 1
                      : t->measure == PLEM_MEASURE_DIGITAL_INPUT ? 32 * n : n;
            if (t->measure < PLEM_MEASURE_POSITION || t->measure >= PLEM_MEASURES || i < 0 || i >= limit) return 0;
            depth++;
            break;
        }
        default: return 0;
        }
    }
    return depth == 1;
}

/* A checked condition's truth for all 256 truths of its comparisons at once: the postfix program runs on 256-bit
 * lanes, comparison j being true in the lanes whose index has bit j set. */
static void truth_table(const plem_reaction *r, uint64_t table[4]) {
    static const uint64_t alternating[6] = {0xAAAAAAAAAAAAAAAAULL, 0xCCCCCCCCCCCCCCCCULL, 0xF0F0F0F0F0F0F0F0ULL,
                                            0xFF00FF00FF00FF00ULL, 0xFFFF0000FFFF0000ULL, 0xFFFFFFFF00000000ULL};
    uint64_t stack[PLEM_REACTION_TERMS][4];
    int depth = 0, j = 0;
    for (int k = 0; k < r->terms; k++) {
        int op = r->term[k].op;
        if (op == PLEM_TERM_AND || op == PLEM_TERM_OR) {
            uint64_t *below = stack[depth - 2], *top = stack[depth - 1];
            for (int w = 0; w < 4; w++) below[w] = op == PLEM_TERM_AND ? below[w] & top[w] : below[w] | top[w];
            depth--;
        } else if (op == PLEM_TERM_NOT) {
            for (int w = 0; w < 4; w++) stack[depth - 1][w] = ~stack[depth - 1][w];
        } else {
            for (int w = 0; w < 4; w++) stack[depth][w] = j < 6 ? alternating[j] : (w >> (j - 6) & 1) ? ~0ULL : 0;
            depth++, j++;
        }
    }
    memcpy(table, stack[0], sizeof stack[0]);
}

/* Arm or disarm a reaction slot: its flag (which Python reads), its bit in the set the cycle walks, its truth table
 * when armed, and the program's comparisons, rebuilt from every armed slot. Arming starts with its condition false. */
COLD static void set_armed(plem_arm *arm, int slot, int armed) {
    plem_program *p = &arm->program;
    arm->reactions[slot].armed = armed;
    if (armed) arm->reacting |= 1u << slot, truth_table(&arm->reactions[slot], p->slot[slot].table);
    else arm->reacting &= ~(1u << slot);
    p->was_true &= ~(1u << slot);
    int next = 0;
    p->uses = p->bound = 0;
    for (uint32_t left = arm->reacting; left; left &= left - 1) {
        int k = __builtin_ctz(left);
        const plem_reaction *r = &arm->reactions[k];
        p->slot[k].start = (int16_t)next;
        if (r->motion) p->bound |= 1u << k;
        for (int t = 0; t < r->terms; t++) {
            const plem_term *term = &r->term[t];
            if (term->op >= PLEM_TERM_AND) continue;
            p->comparison[next++] = (plem_comparison){.holds_if = (int8_t)(1 << (term->op - PLEM_TERM_ABOVE)),
                                                      .measure = (int8_t)term->measure,
                                                      .index = term->index, .threshold = term->threshold};
            p->uses |= 1u << term->measure;
        }
        p->slot[k].comparisons = (int16_t)(next - p->slot[k].start);
    }
}

static int override_ramping(const plem_override *o) { return o->factor != o->target || o->rate != 0.0; }

/* A new basis: plans made from the old one are stale from now on (the seqlock keeps readers from tearing it). */
static void rebase(plem_arm *arm) {
    plem_basis *b = &arm->basis;
    _Atomic uint64_t *sequence = (_Atomic uint64_t *)&b->sequence;
    atomic_store_explicit(sequence, b->sequence + 1, memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    b->generation++;
    b->slot = arm->active ? arm->active_slot : -1;
    b->segments = arm->active ? arm->active_segments : 0;
    int overridden = arm->active && arm->active_slot >= 0;
    b->start_cycle = !arm->active ? 0 : overridden ? arm->cycle : arm->active_start_cycle;
    b->time = overridden ? arm->override.time : 0.0;
    b->rate = overridden ? arm->override.factor : 1.0;
    b->ramping = overridden && override_ramping(&arm->override);
    memcpy(b->hold_position, row(arm, COMMAND), (size_t)arm->settings.dof * sizeof(double));
    atomic_store_explicit(sequence, b->sequence + 1, memory_order_release);
    reach_from_command(arm);
}

COLD static void end_motion(plem_arm *arm, int outcome, int joint, double v0, double v1) {
    uint64_t token = arm->active_token;
    int slot = arm->active_slot;
    arm->active = 0;
    arm->stream.session = 0;
    rebase(arm);
    if (arm->mode == PLEM_TRAJECTORY) set_mode(arm, PLEM_HOLD, PLEM_CAUSE_MOTION_FINISHED, token, slot);
    if (token && outcome) {
        emit(arm, PLEM_EVENT_MOTION_FINISHED, outcome, -1, joint, outcome, token, v0, v1, 0, 0);
        answer(arm, token, PLEM_FINISHED, outcome, arm->mode, 0, joint, v0, v1);
    }
}

/* Replace whatever runs by the quickest jerk-limited stop from the current command: the stop's time starts at the
 * cycle whose command that is, so the cycle that follows it takes the stop's next step, never the same command. */
COLD static void start_stop(plem_arm *arm, const plem_slab *slab) {
    int n = arm->settings.dof, moving = 0;
    for (int i = 0; i < n; i++) moving |= row(arm, COMMAND + 1)[i] != 0.0 || row(arm, COMMAND + 2)[i] != 0.0;
    if (!moving) {
        rebase(arm);
        return;
    }
    double acceleration[PLEM_MAX_JOINTS], jerk[PLEM_MAX_JOINTS];
    for (int i = 0; i < n; i++)
        acceleration[i] = arm->settings.max_acceleration[i] * INSIDE, jerk[i] = arm->settings.max_jerk[i] * INSIDE;
    arm->stop_segments = plem_plan_stop(n, row(arm, COMMAND), row(arm, COMMAND + 1), row(arm, COMMAND + 2),
                                        acceleration, jerk, arm->stop_knots, arm->stop_coefficients, arm->stop_final);
    arm->active = 1, arm->active_slot = PLEM_STOP_SLOT, arm->active_segments = arm->stop_segments;
    arm->active_token = 0, arm->active_start_cycle = arm->cycle - !arm->commanded;
    arm->settle_deadline = -1, arm->active_cursor = 0;
    arm->active_has_path = arm->active_has_goal = 0;
    for (int r = 0; r < 3; r++)
        for (int i = 0; i < n; i++) arm->active_final[r][i] = arm->stop_final[r * n + i];
    plem_motion motion;
    active_motion(arm, slab, &motion);
    double out[3 * PLEM_MAX_JOINTS];
    arm->active_ended = plem_motion_sample(&motion, 0.0, out);
    for (int r = 0; r < 3; r++) memcpy(row(arm, COMMAND + r), out + r * n, (size_t)n * sizeof(double));
    rebase(arm);
}

/* ---- faults ----------------------------------------------------------------------------------------------- */

COLD static void fault(plem_arm *arm, const plem_slab *slab, int cause, int joint, int detail, double v0, double v1,
                       double v2) {
    if (arm->mode == PLEM_FAULTED) return;
    int previous = arm->mode;
    arm->fault_cause = cause;
    arm->mode = PLEM_FAULTED;
    emit(arm, PLEM_EVENT_FAULT, cause, previous, joint, detail, 0, v0, v1, v2, 0);
    arm->have_previous = 0;
    arm->braking = 0;
    if (arm->active) {
        uint64_t token = arm->active_token;
        arm->active = 0;
        arm->stream.session = 0;
        if (token) answer(arm, token, PLEM_FINISHED, PLEM_ANSWER_FAULT_ABORTED, arm->mode, cause, joint, 0, 0);
    }
    if (arm->pending && arm->pending_token) reject(arm, arm->pending_token, PLEM_ANSWER_FAULTED, cause, -1, 0, 0);
    arm->pending = 0;
    if (previous == PLEM_FREE_DRIVE) leave_free_drive(arm);
    if (previous != PLEM_IDLE && can_command(arm)) start_stop(arm, slab);
    else rebase(arm);
}

void plem_arm_fault(plem_arm *arm, int cause, double value0, double value1) {
    fault(arm, NULL, cause, -1, 0, value0, value1, 0);
}

/* Fault on drive faults, implausible encoder jumps, limit breaches and tracking errors. */
static void supervise_measurement(plem_arm *arm, const plem_slab *slab) {
    const plem_settings *s = &arm->settings;
    int n = s->dof, mode = arm->mode;
    const double *position = row(arm, POSITION), *velocity = row(arm, VELOCITY), *command = row(arm, COMMAND);
    if (mode != PLEM_IDLE)
        for (int i = 0; i < n; i++)
            if (!drive_enabled(arm, i)) {
                int cause = arm->io_statusword[i] & STATUS_FAULT_BIT ? PLEM_CAUSE_DRIVE_FAULT : PLEM_CAUSE_DRIVE_DISABLED;
                fault(arm, slab, cause, i, arm->io_statusword[i], arm->io_error_code[i], 0, 0);
                return;
            }
    if (!arm->have_previous) {
        memcpy(arm->previous_position, position, (size_t)n * sizeof(double));
        arm->have_previous = 1;
    }
    double measure[4][PLEM_MAX_JOINTS], bound[4][PLEM_MAX_JOINTS];
    for (int i = 0; i < n; i++) {
        double center, half;
        range_of(arm, i, &center, &half);
        measure[0][i] = fabs(position[i] - arm->previous_position[i]);
        measure[1][i] = fabs(position[i] - center);
        measure[2][i] = fabs(velocity[i]);
        measure[3][i] = fabs(command[i] - position[i]);
        bound[0][i] = 2.0 * s->max_velocity[i] * s->dt + 1e-3;
        bound[1][i] = mode == PLEM_IDLE ? INFINITY : half + s->position_margin;
        bound[2][i] = mode == PLEM_IDLE ? INFINITY : s->max_velocity[i] * s->velocity_margin + 0.01;
        bound[3][i] = mode == PLEM_IDLE || mode == PLEM_FREE_DRIVE ? INFINITY : s->tracking_tolerance;
    }
    memcpy(arm->previous_position, position, (size_t)n * sizeof(double));
    for (int r = 0; r < 4; r++)
        for (int i = 0; i < n; i++) {
            if (!(measure[r][i] > bound[r][i])) continue;
            switch (r) {
            case 0: fault(arm, slab, PLEM_CAUSE_ENCODER_JUMP, i, 0, measure[r][i], bound[r][i], 0); break;
            case 1: fault(arm, slab, PLEM_CAUSE_POSITION_LIMIT, i, 0, position[i], s->min_position[i],
                          s->max_position[i]); break;
            case 2: fault(arm, slab, PLEM_CAUSE_VELOCITY_LIMIT, i, 0, velocity[i], s->max_velocity[i], 0); break;
            default: fault(arm, slab, PLEM_CAUSE_TRACKING_ERROR, i, 0, measure[r][i], bound[r][i], 0); break;
            }
            return;
        }
}

/* In FAULT with drives enabled, the drives hold the arm where the stop leaves it. When they cannot (it runs away
 * from its command or past its velocity limit), disable them so the brakes hold it, and say so. */
static void supervise_fault_hold(plem_arm *arm) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    for (int r = 2; r < 4; r++)
        for (int i = 0; i < n; i++) {
            if (!drive_enabled(arm, i)) continue;   /* a disabled drive's joint is on its brake */
            double value = r == 2 ? fabs(row(arm, VELOCITY)[i]) : fabs(row(arm, COMMAND)[i] - row(arm, POSITION)[i]);
            double bound = r == 2 ? s->max_velocity[i] * s->velocity_margin + 0.01 : s->tracking_tolerance;
            if (!(value > bound)) continue;
            request_power(arm, PLEM_SWITCH_ON_DISABLED);
            arm->braking = 1;
            emit(arm, PLEM_EVENT_WARNING, PLEM_CAUSE_BRAKES_ENGAGED, -1, i, r,
                 0, r == 2 ? row(arm, VELOCITY)[i] : value, r == 2 ? s->max_velocity[i] : bound, 0, 0);
            return;
        }
}

/* ---- requests ----------------------------------------------------------------------------------------------- */

/* The arm must stand still for `action`; 0 and a refusal when it does not. */
static int require_standstill(plem_arm *arm, uint64_t token, int action) {
    int n = arm->settings.dof, fastest = 0, moving = 0;
    const double *velocity = row(arm, VELOCITY);
    for (int i = 0; i < n; i++) {
        if (fabs(velocity[i]) > fabs(velocity[fastest])) fastest = i;
        moving |= fabs(velocity[i]) > arm->settings.standstill_velocity;
    }
    if (!arm->active && !moving) return 1;
    reject(arm, token, PLEM_ANSWER_MOVING, action, moving ? fastest : -1, fabs(velocity[fastest]), 0);
    return 0;
}

static void start_enable(plem_arm *arm, int target, uint64_t token, int after_reset) {
    set_io_mode(arm, target == PLEM_FREE_DRIVE ? PLEM_CST : PLEM_CSP);
    if (!after_reset) request_power(arm, PLEM_OPERATION_ENABLED);
    int64_t timeout = arm->settings.enable_timeout_cycles;
    arm->pending = 1, arm->pending_target = target, arm->pending_token = token;
    arm->pending_deadline = arm->cycle + (timeout > 1 ? timeout : 1);
    arm->pending_enable_sent = !after_reset;
}

/* The drive states of joints 8k..8k+7, four bits each, as a number a double holds exactly. */
static double packed_states(const plem_arm *arm, int k) {
    uint64_t packed = 0;
    for (int i = 8 * k; i < arm->settings.dof && i < 8 * k + 8; i++)
        packed |= (uint64_t)plem_decode_statusword(arm->io_statusword[i]) << (4 * (i - 8 * k));
    return (double)packed;
}

static void advance_enable(plem_arm *arm) {
    int n = arm->settings.dof, all_enabled = 1, any_fault = 0;
    for (int i = 0; i < n; i++) {
        int state = plem_decode_statusword(arm->io_statusword[i]);
        all_enabled &= state == PLEM_OPERATION_ENABLED;
        any_fault |= state == PLEM_FAULT;
    }
    if (!arm->pending_enable_sent && !any_fault) {
        request_power(arm, PLEM_OPERATION_ENABLED);
        arm->pending_enable_sent = 1;
    }
    int target = arm->pending_target;
    uint64_t token = arm->pending_token;
    if (all_enabled) {
        arm->pending = 0;
        seed_from_measurement(arm);
        memset(arm->previous_acceleration, 0, sizeof arm->previous_acceleration);
        rebase(arm);
        if (arm->mode == PLEM_FAULTED) {
            int mode = arm->mode;
            arm->mode = target;   /* the event carries the mode the reset leads to */
            emit(arm, PLEM_EVENT_FAULT_CLEARED, PLEM_CAUSE_RESET, -1, -1, arm->fault_cause, 0, 0, 0, 0, 0);
            arm->mode = mode;
            arm->fault_cause = 0;
        }
        set_mode(arm, target, PLEM_CAUSE_DRIVES_ENABLED, 0, 0);
        if (token) answer(arm, token, PLEM_FINISHED, PLEM_ANSWER_MODE, target, 0, -1, 0, 0);
    } else if (arm->cycle >= arm->pending_deadline) {
        arm->pending = 0;
        request_power(arm, PLEM_SWITCH_ON_DISABLED);
        if (token) reject(arm, token, PLEM_ANSWER_ENABLE_TIMEOUT, target, -1, packed_states(arm, 0),
                          packed_states(arm, 1));
        emit(arm, PLEM_EVENT_COMMAND_REJECTED, PLEM_CAUSE_ENABLE_TIMEOUT, -1, -1, target, token,
             packed_states(arm, 0), packed_states(arm, 1), 0, 0);
    }
}

/* Which modes set_mode may ask for from each mode (TRAJECTORY comes by starting a motion; FAULT is left by reset). */
static int requestable(int current, int requested) {
    static const uint8_t allowed[5] = {
        [PLEM_IDLE] = 1 << PLEM_IDLE | 1 << PLEM_HOLD | 1 << PLEM_FREE_DRIVE,
        [PLEM_HOLD] = 1 << PLEM_HOLD | 1 << PLEM_IDLE | 1 << PLEM_FREE_DRIVE,
        [PLEM_TRAJECTORY] = 1 << PLEM_HOLD,
        [PLEM_FREE_DRIVE] = 1 << PLEM_FREE_DRIVE | 1 << PLEM_HOLD | 1 << PLEM_IDLE,
        [PLEM_FAULTED] = 0,
    };
    return requested >= 0 && requested <= PLEM_FAULTED && (allowed[current] >> requested & 1);
}

static void request_mode(plem_arm *arm, const plem_slab *slab, const plem_command *c) {
    int current = arm->mode, requested = c->mode;
    if (arm->pending) return reject(arm, c->token, PLEM_ANSWER_MODE_PENDING, arm->pending_target, -1, 0, 0);
    if (!requestable(current, requested)) return reject(arm, c->token, PLEM_ANSWER_TRANSITION, requested, -1, 0, 0);
    if (requested == current) return answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_MODE, current, 0, -1, 0, 0);
    if (requested == PLEM_IDLE) {
        if (!require_standstill(arm, c->token, 0)) return;
        request_power(arm, PLEM_SWITCH_ON_DISABLED);
        arm->active = 0;
        set_mode(arm, PLEM_IDLE, PLEM_CAUSE_SET_MODE_IDLE, 0, 0);
        seed_from_measurement(arm);
        answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_MODE, PLEM_IDLE, 0, -1, 0, 0);
    } else if (current == PLEM_IDLE) {
        start_enable(arm, requested, c->token, 0);
    } else if (requested == PLEM_FREE_DRIVE) {
        if (!require_standstill(arm, c->token, 1)) return;
        set_io_mode(arm, PLEM_CST);
        arm->active = 0;
        set_mode(arm, PLEM_FREE_DRIVE, PLEM_CAUSE_SET_MODE_FREE_DRIVE, 0, 0);
        answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_MODE, PLEM_FREE_DRIVE, 0, -1, 0, 0);
    } else {   /* HOLD from free drive or a motion: stop smoothly from where the arm is */
        if (current == PLEM_FREE_DRIVE) leave_free_drive(arm);
        else if (arm->active && arm->active_token) end_motion(arm, PLEM_ANSWER_CANCELED, -1, 0, 0);
        set_mode(arm, PLEM_HOLD, PLEM_CAUSE_SET_MODE_HOLD, 0, 0);
        start_stop(arm, slab);
        answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_MODE, PLEM_HOLD, 0, -1, 0, 0);
    }
}

/* The running motion (not the core's own stop) is replaced by a newer one: say so to whoever waits for it. */
static void preempt(plem_arm *arm) {
    if (!arm->active || !arm->active_token) return;
    answer(arm, arm->active_token, PLEM_FINISHED, PLEM_ANSWER_PREEMPTED, arm->mode, 0, -1, 0, 0);
    emit(arm, PLEM_EVENT_MOTION_FINISHED, PLEM_ANSWER_PREEMPTED, -1, -1, PLEM_ANSWER_PREEMPTED, arm->active_token,
         0, 0, 0, 0);
}

/* The follower runs the arm from now on, from the command as it is, toward `target` (positions for `kind`
 * PLEM_STREAM_POSITION, else velocities); `internal`: a fixed target with no samples and no timeout. */
static void begin_following(plem_arm *arm, uint64_t token, int kind, const double *target, int internal) {
    int n = arm->settings.dof;
    plem_stream *st = &arm->stream;
    st->session = token, st->last_cycle = arm->cycle, st->last_count = 0, st->last_stamp = 0, st->feed_until = 0;
    st->kind = kind, st->timed_out = 0, st->internal = internal;
    for (int i = 0; i < n; i++) st->target[i] = target[i], st->feed[i] = 0.0;
    arm->active = 1, arm->active_ended = 0, arm->active_slot = PLEM_STREAM_SLOT, arm->active_segments = 0;
    arm->active_token = token, arm->active_start_cycle = arm->cycle, arm->settle_deadline = -1;
    arm->active_has_path = arm->active_has_goal = 0;
    rebase(arm);
}

/* Follow the stream block from now on, from the command as it is (a running motion is taken over where it is). */
static void start_stream(plem_arm *arm, const plem_command *c) {
    static const double at_rest[PLEM_MAX_JOINTS] = {0};   /* until the first sample: come to rest */
    if ((arm->mode != PLEM_HOLD && arm->mode != PLEM_TRAJECTORY) || arm->pending)
        return reject(arm, c->token, PLEM_ANSWER_NOT_HOLDING, arm->pending, -1, 0, 0);
    if (c->cycles < 1) return reject(arm, c->token, PLEM_ANSWER_INVALID_VALUE, 0, -1, (double)c->cycles, 0);
    preempt(arm);
    begin_following(arm, c->token, PLEM_STREAM_VELOCITY, at_rest, 0);
    arm->stream.timeout_cycles = c->cycles;
    answer(arm, c->token, PLEM_ACCEPTED, 0, arm->mode, 0, -1, 0, 0);
    set_mode(arm, PLEM_TRAJECTORY, PLEM_CAUSE_MOTION_STARTED, c->token, 0);
    emit(arm, PLEM_EVENT_MOTION_STARTED, PLEM_CAUSE_MOTION_STARTED, -1, -1, 1, c->token, INFINITY, 0, 0, 0);
}

/* The last body's inertials become the command's (the description's own with a payload added, from Python). */
static void set_payload(plem_arm *arm, const plem_command *c) {
    const double *body = c->body;
    for (int i = 0; i < 13; i++)
        if (!isfinite(body[i])) return reject(arm, c->token, PLEM_ANSWER_INVALID_VALUE, 0, -1, body[i], 0);
    if (!(body[0] >= 0.0)) return reject(arm, c->token, PLEM_ANSWER_INVALID_VALUE, 0, -1, body[0], 0);
    int last = arm->model.dof - 1;
    arm->model.mass[last] = body[0];
    memcpy(arm->model.com[last], body + 1, sizeof arm->model.com[last]);
    memcpy(arm->model.inertia[last], body + 4, sizeof arm->model.inertia[last]);
    answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_DONE, arm->mode, 0, -1, 0, 0);
}

static void set_override(plem_arm *arm, const plem_command *c) {
    if (!(c->value >= 0.0 && c->value <= 1.0))
        return reject(arm, c->token, PLEM_ANSWER_INVALID_VALUE, 0, -1, c->value, 0);
    arm->override.target = c->value;
    answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_DONE, arm->mode, 0, -1, 0, 0);
}

static void activate(plem_arm *arm, const plem_slab *slab, const plem_command *c) {
    int n = arm->settings.dof;
    if ((arm->mode != PLEM_HOLD && arm->mode != PLEM_TRAJECTORY) || arm->pending)
        return reject(arm, c->token, PLEM_ANSWER_NOT_HOLDING, arm->pending, -1, 0, 0);
    int32_t capacity;
    const double *values = slab_slot(slab, n, c->slot, &capacity);
    if (!values || c->segments < 0 || c->segments > capacity || (int32_t)values[0] != c->segments)
        return reject(arm, c->token, PLEM_ANSWER_INVALID_SLOT, c->slot, -1, c->segments, values ? values[0] : -1);
    if (arm->active && arm->active_slot == PLEM_STREAM_SLOT)
        return reject(arm, c->token, PLEM_ANSWER_STREAMING, 0, -1, 0, 0);
    if (c->basis != arm->basis.generation || (c->activation >= 0 && arm->cycle != c->activation)
        || (c->activation >= 0 && arm->basis.ramping))
        return reject(arm, c->token, PLEM_ANSWER_STALE, 0, -1, 0, 0);
    preempt(arm);
    arm->override.time = 0.0;
    for (int r = 0; r < 3; r++)
        for (int i = 0; i < n; i++) {   /* unknown peaks count as the limits */
            const plem_settings *s = &arm->settings;
            double limit = r == 0 ? s->max_velocity[i] : r == 1 ? s->max_acceleration[i] : s->max_jerk[i];
            arm->override.peaks[r][i] = c->peaks[r][i] > 0.0 ? fmin(c->peaks[r][i], limit) : c->peaks[r][i] == 0.0
                                        ? 0.0 : limit;
        }
    arm->active = 1, arm->active_ended = 0, arm->active_slot = c->slot, arm->active_segments = c->segments;
    arm->active_token = c->token, arm->active_start_cycle = arm->cycle, arm->settle_deadline = -1;
    arm->active_cursor = 0, arm->active_has_path = c->has_path, arm->active_has_goal = c->has_goal;
    arm->active_goal_time = c->goal_time, arm->active_stopped_velocity = c->stopped_velocity;
    memcpy(arm->active_path, c->path, sizeof arm->active_path);
    memcpy(arm->active_goal, c->goal_tolerance, sizeof arm->active_goal);
    for (int r = 0; r < 3; r++)
        for (int i = 0; i < n; i++) arm->active_final[r][i] = values[1 + r * n + i];
    rebase(arm);
    answer(arm, c->token, PLEM_ACCEPTED, 0, arm->mode, 0, -1, 0, 0);
    set_mode(arm, PLEM_TRAJECTORY, PLEM_CAUSE_MOTION_STARTED, c->token, 0);
    double duration = c->segments > 0 ? values[1 + 3 * n + c->segments] : 0.0;
    emit(arm, PLEM_EVENT_MOTION_STARTED, PLEM_CAUSE_MOTION_STARTED, -1, -1, 0, c->token, duration, 0, 0, 0);
}

static void reset(plem_arm *arm, const plem_command *c) {
    if (arm->mode != PLEM_FAULTED) return answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_MODE, arm->mode, 0, -1, 0, 0);
    if (!arm->communication_ok) return reject(arm, c->token, PLEM_ANSWER_RESET_NO_BUS, arm->fault_cause, -1, 0, 0);
    if (!require_standstill(arm, c->token, 2)) return;
    arm->active = 0;
    arm->power_resets++;
    plem_power_request_reset(&arm->power);
    start_enable(arm, PLEM_HOLD, c->token, 1);
}

COLD static void execute(plem_arm *arm, const plem_slab *slab, const plem_command *c) {
    switch (c->op) {
    case PLEM_OP_START:
        arm->last_start = c->token;
        activate(arm, slab, c);
        break;
    case PLEM_OP_SET_MODE: request_mode(arm, slab, c); break;
    case PLEM_OP_STOP:
        if (arm->active && arm->active_token && (c->goal == 0 || c->goal == arm->active_token)) {
            end_motion(arm, PLEM_ANSWER_CANCELED, -1, 0, 0);
            start_stop(arm, slab);
        }
        answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_DONE, arm->mode, 0, -1, 0, 0);
        break;
    case PLEM_OP_RESET: reset(arm, c); break;
    case PLEM_OP_STREAM: start_stream(arm, c); break;
    case PLEM_OP_OVERRIDE: set_override(arm, c); break;
    case PLEM_OP_REACT:
    case PLEM_OP_UNREACT:
        if (c->slot < 0 || c->slot >= PLEM_REACTIONS)
            return reject(arm, c->token, PLEM_ANSWER_INVALID_VALUE, 0, -1, c->slot, 0);
        if (c->op == PLEM_OP_REACT && !well_formed(arm, &arm->reactions[c->slot]))
            return reject(arm, c->token, PLEM_ANSWER_MALFORMED_REACTION, c->slot, -1, 0, 0);
        set_armed(arm, c->slot, c->op == PLEM_OP_REACT);
        answer(arm, c->token, PLEM_FINISHED, PLEM_ANSWER_DONE, arm->mode, 0, -1, 0, 0);
        break;
    case PLEM_OP_PAYLOAD: set_payload(arm, c); break;
    default: reject(arm, c->token, PLEM_ANSWER_UNKNOWN_OP, c->op, -1, 0, 0);
    }
}

/* Take at most PLEM_COMMANDS_PER_CYCLE requests; a start planned to take over at a later cycle waits at the head. */
static void take_commands(plem_arm *arm, const plem_slab *slab) {
    plem_ring *ring = &arm->commands_index;
    for (int taken = 0; taken < PLEM_COMMANDS_PER_CYCLE; taken++) {
        uint64_t tail = ring->tail, head = atomic_load_explicit((_Atomic uint64_t *)&ring->head, memory_order_acquire);
        if (tail == head) return;
        const plem_command *c = &arm->commands[tail % PLEM_COMMAND_SLOTS];
        if (c->op == PLEM_OP_START && c->activation >= 0 && c->basis == arm->basis.generation
            && arm->cycle < c->activation)
            return;
        execute(arm, slab, c);
        atomic_store_explicit((_Atomic uint64_t *)&ring->tail, tail + 1, memory_order_release);
    }
}

/* ---- what the arm feels, and reactions ------------------------------------------------------------------------ */

/* The external joint torque: the model's effort for last cycle's command acceleration at the measured state (the
 * dynamics free drive uses for gravity, plus viscous friction) less the measured effort; and the flange wrench
 * that explains it. Then the standing contact stop: past its threshold on any joint, the arm faults and stops.
 * Not estimated for PLEM_UNSETTLED_S after a stale bus answer: the drives then catch up with a command that jumped,
 * an acceleration the model's was not. */
static void feel(plem_arm *arm, const plem_slab *slab) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    int settled = arm->unsettled == 0;
    if (!settled) arm->unsettled--;
    arm->feeling = (arm->mode == PLEM_HOLD || arm->mode == PLEM_TRAJECTORY) && !arm->pending && can_command(arm)
                   && settled;
    if (!arm->feeling) {
        memset(arm->external, 0, sizeof arm->external);
        memset(arm->wrench, 0, sizeof arm->wrench);
        return;
    }
    plem_inverse_dynamics(&arm->model, row(arm, POSITION), row(arm, VELOCITY), row(arm, COMMAND + 2), arm->external);
    for (int i = 0; i < n; i++)
        arm->external[i] += s->friction[i] * row(arm, VELOCITY)[i] - row(arm, EFFORT)[i];
    plem_tool_wrench(&arm->model, row(arm, POSITION), arm->external, arm->wrench);
    for (int i = 0; i < n; i++)
        if (fabs(arm->external[i]) > s->contact_threshold[i]) {
            fault(arm, slab, PLEM_CAUSE_CONTACT, i, 0, arm->external[i], s->contact_threshold[i], 0);
            return;
        }
}

/* Where each measure's values are this cycle, indexed by a step's index (a joint, or a wrench component); NaN
 * for a quantity without a value: an estimate not current, a motion time with no motion. Digital inputs are read
 * by `digital_input`. The rest holds what is worked out for the cycle: following errors, drive states, the time. */
typedef struct {
    const double *of[PLEM_MEASURES];
    double following[PLEM_MAX_JOINTS], states[PLEM_MAX_JOINTS], motion_time;
} measures;

static const double NOT_MEASURED[PLEM_MAX_JOINTS] = {
    NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN};

/* This cycle's measures, computing only those an armed reaction compares. */
static void measure(const plem_arm *arm, measures *m) {
    int n = arm->settings.dof;
    uint32_t uses = arm->program.uses;
    m->of[PLEM_MEASURE_POSITION] = arm->work[POSITION];
    m->of[PLEM_MEASURE_VELOCITY] = arm->work[VELOCITY];
    m->of[PLEM_MEASURE_EFFORT] = arm->work[EFFORT];
    m->of[PLEM_MEASURE_EXTERNAL_TORQUE] = arm->feeling ? arm->external : NOT_MEASURED;
    m->of[PLEM_MEASURE_WRENCH] = arm->feeling ? arm->wrench : NOT_MEASURED;
    m->of[PLEM_MEASURE_FOLLOWING_ERROR] = m->following;
    m->of[PLEM_MEASURE_MOTION_TIME] = &m->motion_time;
    m->of[PLEM_MEASURE_DRIVE_STATE] = m->states;
    if (uses >> PLEM_MEASURE_FOLLOWING_ERROR & 1u)
        for (int i = 0; i < n; i++) m->following[i] = fabs(arm->work[COMMAND][i] - arm->work[POSITION][i]);
    if (uses >> PLEM_MEASURE_DRIVE_STATE & 1u)
        for (int i = 0; i < n; i++) m->states[i] = (double)plem_decode_statusword(arm->io_statusword[i]);
    if (uses >> PLEM_MEASURE_MOTION_TIME & 1u)
        m->motion_time = arm->active ? (double)(arm->cycle - arm->active_start_cycle) * arm->settings.dt : NAN;
}

/* A drive's digital input (index joint · 32 + bit), NaN from a drive that does not report them. */
static double digital_input(const plem_arm *arm, int index) {
    int drive = index / 32, bit = index % 32;
    return arm->io_inputs_reported >> drive & 1u ? (double)(arm->io_digital_inputs[drive] >> bit & 1u) : NAN;
}

static double value_of(const plem_arm *arm, const measures *m, const plem_comparison *c) {
    return c->measure == PLEM_MEASURE_DIGITAL_INPUT ? digital_input(arm, c->index) : m->of[c->measure][c->index];
}

/* An armed slot's condition now: its comparisons' truths as an index into its truth table. */
static uint32_t holds(const plem_arm *arm, const measures *m, const plem_armed *a) {
    const plem_comparison *c = &arm->program.comparison[a->start];
    uint32_t index = 0;
    for (int j = 0; j < a->comparisons; j++) {
        double value = value_of(arm, m, &c[j]), threshold = c[j].threshold;
        uint32_t relation = (uint32_t)(value > threshold) | (uint32_t)(value < threshold) << 1
                            | (uint32_t)(value == threshold) << 2;   /* none for NaN */
        index |= (uint32_t)((relation & (uint32_t)c[j].holds_if) != 0) << j;
    }
    return (uint32_t)(a->table[index >> 6] >> (index & 63) & 1u);
}

COLD static void fire(plem_arm *arm, const plem_slab *slab, int slot, double value, double threshold) {
    plem_reaction *r = &arm->reactions[slot];
    emit(arm, PLEM_EVENT_REACTION, PLEM_CAUSE_REACTION, -1, slot, r->action, r->token, value, threshold, 0, 0);
    int enabled = arm->mode == PLEM_HOLD || arm->mode == PLEM_TRAJECTORY;   /* the drives follow the command */
    if (r->once || r->motion) set_armed(arm, slot, 0);
    switch (r->action) {
    case PLEM_REACT_STOP:
        if (arm->active && arm->active_token) {
            end_motion(arm, PLEM_ANSWER_REACTED, slot, value, threshold);
            start_stop(arm, slab);
        }
        break;
    case PLEM_REACT_HOLD:
        if (enabled) arm->override.target = 0.0;   /* a fault's stop runs at full speed, and a reset resumes at it */
        break;
    case PLEM_REACT_FREE_DRIVE:
        if (!enabled) break;
        if (arm->active && arm->active_token) end_motion(arm, PLEM_ANSWER_REACTED, slot, value, threshold);
        arm->active = 0;
        set_io_mode(arm, PLEM_CST);
        set_mode(arm, PLEM_FREE_DRIVE, PLEM_CAUSE_SET_MODE_FREE_DRIVE, r->token, 0);
        break;
    case PLEM_REACT_MOVE:
        if (!enabled) break;
        if (arm->active && arm->active_token) end_motion(arm, PLEM_ANSWER_REACTED, slot, value, threshold);
        begin_following(arm, r->token, PLEM_STREAM_POSITION, r->target, 1);   /* a stream with a fixed target */
        set_mode(arm, PLEM_TRAJECTORY, PLEM_CAUSE_MOTION_STARTED, r->token, 0);
        break;
    default: break;
    }
}

/* Whether reaction `slot` may act now: standing, or its motion is the one running. */
static int in_its_motion(const plem_arm *arm, int slot) {
    uint64_t motion = arm->reactions[slot].motion;   /* an armed slot's record stays as written */
    return !motion || (arm->active && arm->active_token == motion);
}

/* The armed slots of `slots` (bound to motions) whose motion is yet to start: armed before it, each watches from
 * the motion's first cycle. A bound slot whose motion ended or was refused is disarmed. */
static uint32_t waiting(plem_arm *arm, uint32_t slots) {
    uint32_t yet = 0;
    for (; slots; slots &= slots - 1) {
        int slot = __builtin_ctz(slots);
        if (in_its_motion(arm, slot)) continue;
        if (arm->reactions[slot].motion <= arm->last_start) set_armed(arm, slot, 0);
        else yet |= 1u << slot;
    }
    return yet;
}

/* Every armed reaction, on what this cycle measured: an action starts in the cycle its condition rises. The event
 * carries the first comparison's quantity and threshold. */
static void react(plem_arm *arm, const plem_slab *slab) {
    if (!arm->reacting) return;
    plem_program *p = &arm->program;
    measures m;
    measure(arm, &m);
    uint32_t now = 0;
    for (uint32_t left = arm->reacting; left; left &= left - 1) {
        int slot = __builtin_ctz(left);
        now |= holds(arm, &m, &p->slot[slot]) << slot;
    }
    uint32_t yet = p->bound ? waiting(arm, p->bound) : 0;   /* may disarm: read the armed set after it */
    uint32_t live = arm->reacting & ~yet;
    uint32_t rose = now & ~p->was_true & live;
    p->was_true = (p->was_true & ~live) | (now & live);
    for (; rose; rose &= rose - 1) {
        int slot = __builtin_ctz(rose);
        if (!(arm->reacting >> slot & 1u) || !in_its_motion(arm, slot)) continue;   /* an earlier action ended it */
        const plem_comparison *first = &p->comparison[p->slot[slot].start];
        fire(arm, slab, slot, value_of(arm, &m, first), first->threshold);
    }
}

/* ---- control ------------------------------------------------------------------------------------------------ */

/* The running motion leaves its path tolerance: abort it and stop; 1 when it did. */
static int check_path(plem_arm *arm, const plem_slab *slab) {
    int n = arm->settings.dof, worst = -1;
    double excess = -INFINITY;
    for (int i = 0; i < n; i++) {
        double error = fabs(row(arm, COMMAND)[i] - row(arm, POSITION)[i]);
        if (error > arm->active_path[i] && error - arm->active_path[i] > excess) excess = error - arm->active_path[i], worst = i;
    }
    if (worst < 0) return 0;
    end_motion(arm, PLEM_ANSWER_PATH_VIOLATED, worst, fabs(row(arm, COMMAND)[worst] - row(arm, POSITION)[worst]),
               arm->active_path[worst]);
    start_stop(arm, slab);
    return 1;
}

/* After the last point: succeed once inside the goal tolerance and stopped, abort after goal_time. */
static void settle(plem_arm *arm) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    if (!arm->active_token) return end_motion(arm, 0, -1, 0, 0);   /* the core's stop: done once it ends */
    if (arm->settle_deadline < 0) {
        double cycles = arm->active_goal_time / s->dt;
        arm->settle_deadline = arm->cycle + (cycles < (double)MAX_SETTLE_CYCLES
                                             ? (int64_t)fmax(1.0, ceil(cycles)) : MAX_SETTLE_CYCLES);
    }
    int inside = 1, stopped = 1, worst = 0;
    double distance[PLEM_MAX_JOINTS];
    for (int i = 0; i < n; i++) {
        distance[i] = fabs(arm->active_final[0][i] - row(arm, POSITION)[i]);
        if (distance[i] > distance[worst]) worst = i;
        if (arm->active_has_goal && distance[i] > arm->active_goal[i]) inside = 0;
        if (fabs(row(arm, VELOCITY)[i]) > arm->active_stopped_velocity) stopped = 0;
    }
    if (inside && stopped) end_motion(arm, PLEM_ANSWER_SUCCEEDED, -1, 0, 0);
    else if (arm->cycle >= arm->settle_deadline)
        end_motion(arm, PLEM_ANSWER_GOAL_VIOLATED, worst, distance[worst], arm->active_goal_time);
}

/* Fault when the command leaves the position, velocity or acceleration limits, jerks too hard, or is not a number. */
static void check_command(plem_arm *arm, const plem_slab *slab) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    double slack = 1.0 + s->command_tolerance, check[4][PLEM_MAX_JOINTS], bound[4][PLEM_MAX_JOINTS];
    for (int i = 0; i < n; i++) {
        double center, half;
        range_of(arm, i, &center, &half);
        check[0][i] = fabs(row(arm, COMMAND)[i] - center);
        check[1][i] = fabs(row(arm, COMMAND + 1)[i]);
        check[2][i] = fabs(row(arm, COMMAND + 2)[i]);
        check[3][i] = fabs(row(arm, COMMAND + 2)[i] - arm->previous_acceleration[i]);
        bound[0][i] = half * slack + 1e-9;
        bound[1][i] = s->max_velocity[i] * slack + 1e-9;
        bound[2][i] = s->max_acceleration[i] * slack + 1e-9;
        bound[3][i] = s->max_jerk[i] * s->dt * slack + 1e-9;
        arm->previous_acceleration[i] = row(arm, COMMAND + 2)[i];
    }
    for (int r = 0; r < 4; r++)
        for (int i = 0; i < n; i++) {
            if (check[r][i] <= bound[r][i]) continue;
            if (!isfinite(row(arm, COMMAND)[i]) || !isfinite(row(arm, COMMAND + 1)[i])
                || !isfinite(row(arm, COMMAND + 2)[i])) {
                follow_measurement(arm);   /* a stop is planned from where the arm really is, never from NaN */
                fault(arm, slab, PLEM_CAUSE_INVALID_COMMAND, i, 0, 0, 0, 0);
                return;
            }
            static const int causes[4] = {PLEM_CAUSE_COMMAND_POSITION, PLEM_CAUSE_COMMAND_VELOCITY,
                                          PLEM_CAUSE_COMMAND_ACCELERATION, PLEM_CAUSE_COMMAND_JERK};
            double value = r == 3 ? check[3][i] / s->dt : row(arm, COMMAND + r)[i];
            double limit = r == 0 ? s->min_position[i] : r == 1 ? s->max_velocity[i]
                         : r == 2 ? s->max_acceleration[i] : s->max_jerk[i];
            fault(arm, slab, causes[r], i, r, value, limit, s->max_position[i]);
            return;
        }
}

/* ---- the speed override ------------------------------------------------------------------------------------- */

/* One cycle of the factor toward its target. On a running motion with peaks P1, P2, P3 (velocity, acceleration,
 * jerk) in its own time, joint i's command is p'·f (velocity), p''·f² + p'·r (acceleration) and
 * p'''·f³ + 3·p''·f·r + p'·u (jerk), with r and u the factor's rate and its change. So
 *     P2·f² + P1·|r| <= A   and   P3·f³ + 3·P2·f·|r| + P1·|u| <= J
 * keep every limit wherever on the motion the arm is. The rate follows the gain toward the target within a share of
 * the first room, its change within the second: a share small enough (below the root of 4β²x + 6βx = 3 with
 * x = A²/(P1·J), the worst case P2 = A, P3 = J) that the rate can always shrink as fast as its room does. A motion
 * planned at its very limits leaves no room at factor 1: it keeps its speed until it ends. */
static void step_override(plem_arm *arm, int on_motion) {
    const plem_settings *s = &arm->settings;
    plem_override *o = &arm->override;
    double f = o->factor, r = o->rate, dt = s->dt, share = OVERRIDE_SHARE, room = OVERRIDE_RATE;   /* 1/s */
    double change = OVERRIDE_RATE_CHANGE;
    for (int i = 0; on_motion && i < s->dof; i++) {
        double A = s->max_acceleration[i], J = s->max_jerk[i];
        double P1 = o->peaks[0][i], P2 = o->peaks[1][i], P3 = o->peaks[2][i], x = A * A / (P1 * J);
        if (!(P1 > 0.0)) continue;   /* a joint that does not move takes nothing from the factor's change */
        double joint_share = x > 0.0 ? fmin(share, 0.8 * (sqrt(36.0 * x * x + 48.0 * x) - 6.0 * x) / (8.0 * x)) : share;
        room = fmin(room, joint_share * fmax(A - P2 * f * f, 0.0) / P1);
        change = fmin(change, 0.9 * fmax(J - P3 * f * f * f - 3.0 * P2 * f * fabs(r), 0.0) / P1);
    }
    double next = plem_approach(f, r, o->target, room, change, dt);
    double factor = plem_clamp(f + (r + next) * dt / 2.0, 0.0, 1.0);
    if (fabs(o->target - factor) < 1e-12 && fabs(next) < 1e-9) factor = o->target, next = 0.0;
    o->factor = factor, o->rate = next;
}

/* The running slab motion at this cycle under the override, into the command rows; 1 once it ended. */
static int sample_overridden(plem_arm *arm, plem_motion *motion) {
    const plem_settings *s = &arm->settings;
    plem_override *o = &arm->override;
    const plem_basis *b = &arm->basis;
    int n = s->dof;
    double out[3 * PLEM_MAX_JOINTS], before = o->factor;
    if (override_ramping(o)) {
        step_override(arm, 1);
        o->time = arm->cycle == arm->active_start_cycle ? 0.0 : o->time + (before + o->factor) * s->dt / 2.0;
    } else {
        o->time = arm->cycle == arm->active_start_cycle ? 0.0
                : b->time + b->rate * (double)(arm->cycle - b->start_cycle) * s->dt;
    }
    int ended = plem_motion_sample(motion, o->time, out);
    for (int i = 0; i < n; i++) {
        row(arm, COMMAND)[i] = out[i];
        row(arm, COMMAND + 1)[i] = out[n + i] * o->factor;
        row(arm, COMMAND + 2)[i] = out[2 * n + i] * o->factor * o->factor + out[n + i] * o->rate;
    }
    return ended;
}

/* ---- streams -------------------------------------------------------------------------------------------------- */

/* A stream sample's checksum: FNV-1a over its words (plem.control.streaming computes the same). */
static uint64_t stream_checksum(uint64_t session, uint64_t count, int64_t kind, int64_t stamp, const double *target,
                                int n) {
    uint64_t words[4 + PLEM_MAX_JOINTS] = {session, count, (uint64_t)kind, (uint64_t)stamp}, sum = 0xcbf29ce484222325ULL;
    memcpy(words + 4, target, (size_t)n * sizeof(double));
    for (int i = 0; i < 4 + n; i++) sum = (sum ^ words[i]) * 0x100000001b3ULL;
    return sum;
}

/* Take the stream block's sample when it is whole, new, of the running stream and finite. */
static void read_stream(plem_arm *arm, plem_stream_block *block) {
    plem_stream *st = &arm->stream;
    int n = arm->settings.dof;
    if (!block) return;
    _Atomic uint64_t *sequence = (_Atomic uint64_t *)&block->sequence;
    uint64_t before = atomic_load_explicit(sequence, memory_order_acquire);
    uint64_t session = block->session, count = block->count;
    if ((before & 1) || session != st->session || count == st->last_count) return;   /* nothing new: one line read */
    uint64_t checksum = block->checksum;
    int64_t kind = block->kind, stamp = block->stamp_ns;
    double target[PLEM_MAX_JOINTS];
    memcpy(target, block->target, (size_t)n * sizeof(double));
    atomic_thread_fence(memory_order_acquire);
    if (atomic_load_explicit(sequence, memory_order_relaxed) != before
        || checksum != stream_checksum(session, count, kind, stamp, target, n)
        || (kind != PLEM_STREAM_POSITION && kind != PLEM_STREAM_VELOCITY))
        return;
    int finite = 1;
    for (int i = 0; i < n; i++) finite &= isfinite(target[i]) != 0;
    if (!finite) return;
    int feed = kind == PLEM_STREAM_POSITION && st->kind == PLEM_STREAM_POSITION && st->last_count
               && stamp > st->last_stamp;
    double span = feed ? (double)(stamp - st->last_stamp) * 1e-9 : 0.0, rate = feed ? 1.0 / span : 0.0;
    for (int i = 0; i < n; i++) {
        double limit = arm->settings.max_velocity[i];
        st->feed[i] = plem_clamp((target[i] - st->target[i]) * rate, -limit, limit);
        st->target[i] = target[i];
    }
    st->feed_until = arm->cycle + (feed ? (int64_t)ceil(span / arm->settings.dt) : 0);
    st->kind = (int32_t)kind, st->last_count = count, st->last_stamp = stamp, st->last_cycle = arm->cycle;
    st->timed_out = 0;
    block->used_count = count, block->used_cycle = arm->cycle, block->latency_ns = plem_now_ns() - stamp;
}

/* One cycle of the running stream: follow its newest sample; without one for its timeout, come to rest and end. */
static void follow_stream(plem_arm *arm, plem_stream_block *block) {
    const plem_settings *s = &arm->settings;
    plem_stream *st = &arm->stream;
    if (!st->internal) read_stream(arm, block);
    if (!st->internal && arm->cycle - st->last_cycle > st->timeout_cycles) st->timed_out = 1;
    int n = s->dof, position = st->kind == PLEM_STREAM_POSITION && !st->timed_out, at_rest = 1;
    int feeding = position && arm->cycle <= st->feed_until;
    plem_follow_targets targets = {
        .target_position = position ? st->target : NULL,
        .target_velocity = st->timed_out ? NULL : position ? (feeding ? st->feed : NULL) : st->target,
        .max_velocity = s->max_velocity, .max_acceleration = s->max_acceleration, .max_jerk = s->max_jerk,
        .share = INSIDE, .speed = arm->override.factor, .low = arm->reach[0], .high = arm->reach[1]};
    plem_follow(n, row(arm, COMMAND), row(arm, COMMAND + 1), row(arm, COMMAND + 2), &targets, s->dt);
    for (int i = 0; i < n; i++)
        at_rest &= fabs(row(arm, COMMAND + 1)[i]) < 1e-12 && fabs(row(arm, COMMAND + 2)[i]) < 1e-12
                   && (!st->internal || fabs(row(arm, COMMAND)[i] - plem_clamp(st->target[i], arm->reach[0][i],
                                                                             arm->reach[1][i])) < 1e-9);
    if (st->internal && at_rest) return end_motion(arm, PLEM_ANSWER_SUCCEEDED, -1, 0, 0);
    if (st->timed_out && at_rest) {
        memset(row(arm, COMMAND + 1), 0, (size_t)n * sizeof(double));
        memset(row(arm, COMMAND + 2), 0, (size_t)n * sizeof(double));
        end_motion(arm, PLEM_ANSWER_STREAM_TIMED_OUT, -1, (double)st->timeout_cycles, 0);
    }
}

static void publish_stream(const plem_arm *arm, plem_stream_block *block) {
    if (!block) return;
    int streaming = arm->active && arm->active_slot == PLEM_STREAM_SLOT;
    block->used_session = streaming ? arm->stream.session : 0;
    block->state = !streaming ? PLEM_STREAM_NONE : arm->stream.timed_out ? PLEM_STREAM_TIMED_OUT
                 : PLEM_STREAM_FOLLOWING;
    block->speed_override = arm->override.factor;
    block->override_target = arm->override.target;
    memcpy(block->external, arm->external, sizeof block->external);
    memcpy(block->wrench, arm->wrench, sizeof block->wrench);
}

/* ---- control -------------------------------------------------------------------------------------------------- */

/* The running motion at this cycle: the stream's follower, the core's stop in real time, or a slab motion under the
 * speed override (the basis follows the override's ramps). */
static void run_motion(plem_arm *arm, const plem_slab *slab, plem_stream_block *block) {
    int n = arm->settings.dof, aborted = 0, slab_motion = arm->active_slot >= 0;
    if (arm->active_slot == PLEM_STREAM_SLOT) return follow_stream(arm, block);
    if (!arm->active_ended) {
        plem_motion motion;
        if (!active_motion(arm, slab, &motion)) {
            arm->active_ended = 1;  /* the slab went away: hold where the motion was */
        } else if (slab_motion) {
            arm->active_ended = sample_overridden(arm, &motion);
            arm->active_cursor = motion.cursor;
        } else {
            double out[3 * PLEM_MAX_JOINTS];
            arm->active_ended = plem_motion_sample(&motion, (double)(arm->cycle - arm->active_start_cycle)
                                                            * arm->settings.dt, out);
            arm->active_cursor = motion.cursor;
            for (int r = 0; r < 3; r++) memcpy(row(arm, COMMAND + r), out + r * n, (size_t)n * sizeof(double));
        }
        arm->commanded = 1;
        if (arm->active_has_path) aborted = check_path(arm, slab);
    } else if (slab_motion && override_ramping(&arm->override)) {
        step_override(arm, 0);   /* the motion ended: its last state is at rest, nothing left to fit */
    }
    if (slab_motion && arm->active && (override_ramping(&arm->override) != arm->basis.ramping
                                       || arm->basis.rate != arm->override.factor))
        rebase(arm);
    if (arm->active_ended && !aborted) settle(arm);
}

static void control(plem_arm *arm, const plem_slab *slab, plem_stream_block *block) {
    const plem_settings *s = &arm->settings;
    int n = s->dof, mode = arm->mode;
    if (!(arm->active && arm->active_slot >= 0) && override_ramping(&arm->override))
        step_override(arm, 0);   /* no motion it must fit */
    if (mode == PLEM_IDLE || (mode == PLEM_FAULTED && !can_command(arm))) {
        seed_from_measurement(arm);
        if (arm->pending) advance_enable(arm);
        return;
    }
    if (mode == PLEM_FREE_DRIVE) {
        follow_measurement(arm);
        plem_gravity(&arm->model, row(arm, POSITION), arm->torque);
        for (int i = 0; i < n; i++) {
            double torque = arm->torque[i] - s->damping[i] * row(arm, VELOCITY)[i];
            arm->torque[i] = fmax(fmin(torque, s->max_effort[i]), -s->max_effort[i]);
        }
        return;
    }
    if (arm->active) run_motion(arm, slab, block);
    arm->commanded = 1;
    check_command(arm, slab);
    if (arm->pending) advance_enable(arm);
}

/* ---- the bus and publishing --------------------------------------------------------------------------------- */

static int read_bus(plem_arm *arm, const plem_bus *bus) {
    int n = arm->settings.dof;
    plem_sim *sim = bus->sim;
    if (!sim && !bus->master) return arm->io_answered;
    int answered;
    if (sim) {
        answered = plem_sim_read(sim);
        if (answered) {
            memcpy(arm->io_position, sim->io_position, (size_t)n * sizeof(int64_t));
            memcpy(arm->io_velocity, sim->io_velocity, (size_t)n * sizeof(int64_t));
            memcpy(arm->io_torque, sim->io_torque, (size_t)n * sizeof(double));
            memcpy(arm->io_statusword, sim->io_statusword, (size_t)n * sizeof(uint16_t));
            memcpy(arm->io_error_code, sim->io_error_code, (size_t)n * sizeof(uint16_t));
            memcpy(arm->io_digital_inputs, sim->digital_inputs, (size_t)n * sizeof(uint32_t));
            arm->io_inputs_reported = (uint32_t)((1ULL << n) - 1);
        }
    } else {
        answered = plem_master_read(bus->master, arm);
        if (!plem_master_fresh(bus->master)) arm->unsettled = (int32_t)ceil(PLEM_UNSETTLED_S / arm->settings.dt);
    }
    if (!answered) plem_power_master_lost(&arm->power);
    arm->io_answered = answered;
    return answered;
}

static void write_bus(plem_arm *arm, const plem_bus *bus) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    for (int i = 0; i < n; i++) {
        arm->io_target_position[i] = (int64_t)rint(row(arm, COMMAND)[i] * s->counts_per_radian[i]) - s->offsets[i];
        arm->io_velocity_offset[i] = (int64_t)rint(row(arm, COMMAND + 1)[i] * s->counts_per_radian[i]);
        arm->io_torque_offset[i] = arm->mode == PLEM_FREE_DRIVE ? arm->torque[i] : 0.0;
    }
    plem_sim *sim = bus->sim;
    if (!sim && !bus->master) return;
    int32_t seen[PLEM_MAX_JOINTS];
    uint16_t controlwords[PLEM_MAX_JOINTS];
    for (int i = 0; i < n; i++) seen[i] = plem_decode_statusword(arm->io_statusword[i]);
    plem_power_commands(&arm->power, seen, controlwords);
    if (!sim) {
        plem_master_write(bus->master, arm, controlwords);
        return;
    }
    memcpy(sim->io_target_position, arm->io_target_position, (size_t)n * sizeof(int64_t));
    memcpy(sim->io_velocity_offset, arm->io_velocity_offset, (size_t)n * sizeof(int64_t));
    memcpy(sim->io_torque_offset, arm->io_torque_offset, (size_t)n * sizeof(double));
    memcpy(sim->io_mode, arm->io_mode, (size_t)n);
    plem_sim_exchange(sim, controlwords);
}

/* One cycle's state into the seqlock block: sequence odd, the rows and header, sequence even. */
static void publish(plem_arm *arm, plem_state_block *block) {
    if (!block || !block->header) return;
    int n = arm->settings.dof, enabled = arm->mode == PLEM_HOLD || arm->mode == PLEM_TRAJECTORY
                                         || arm->mode == PLEM_FREE_DRIVE;
    _Atomic int64_t *sequence = (_Atomic int64_t *)&block->header[0];
    int64_t value = atomic_load_explicit(sequence, memory_order_relaxed);
    atomic_store_explicit(sequence, value + 1, memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    for (int r = 0; r < 6; r++) memcpy(block->values + r * n, row(arm, r), (size_t)n * sizeof(double));
    block->header[1] = arm->cycle;
    block->header[2] = plem_now_ns();
    block->header[3] = arm->mode;
    block->header[4] = arm->mode == PLEM_FAULTED;
    block->header[5] = enabled;
    atomic_store_explicit(sequence, value + 2, memory_order_release);
}

void plem_arm_init(plem_arm *arm) {
    arm->mode = PLEM_IDLE;
    arm->communication_ok = 1;
    arm->power_wanted = PLEM_SWITCH_ON_DISABLED;
    plem_power_init(&arm->power, arm->settings.dof);
    set_io_mode(arm, PLEM_CSP);
    arm->override.target = arm->override.factor = 1.0;
    rebase(arm);
}

void plem_arm_cycle(plem_arm *arm, const plem_bus *bus, const plem_slab *slab, plem_state_block *block,
                    plem_stream_block *stream) {
    const plem_settings *s = &arm->settings;
    int n = s->dof;
    if (stream && arm->active && arm->active_slot == PLEM_STREAM_SLOT) {
        /* a new sample's lines are in the writer's CPU's cache: fetched now, they are here by the stream's read
         * (measured: a new sample's read 70 ns instead of up to 300 with the writer on the other CPU) */
        __builtin_prefetch(stream);
        __builtin_prefetch(stream->target);
    }
    if (read_bus(arm, bus)) {
        if (!arm->communication_ok) arm->communication_ok = 1, arm->have_previous = 0;
        for (int i = 0; i < n; i++) {
            row(arm, POSITION)[i] = (double)(arm->io_position[i] + s->offsets[i]) / s->counts_per_radian[i];
            row(arm, VELOCITY)[i] = (double)arm->io_velocity[i] / s->counts_per_radian[i];
            row(arm, EFFORT)[i] = arm->io_torque[i];
        }
        if (arm->mode != PLEM_FAULTED) supervise_measurement(arm, slab);
        else if (!arm->braking && can_command(arm)) supervise_fault_hold(arm);
        if (arm->mode != PLEM_FAULTED) feel(arm, slab);
        react(arm, slab);
    } else if (arm->communication_ok) {
        arm->communication_ok = 0;
        fault(arm, slab, PLEM_CAUSE_COMMUNICATION_LOST, -1, 0, 0, 0, 0);
    }
    take_commands(arm, slab);
    control(arm, slab, stream);
    write_bus(arm, bus);
    arm->cycle++;
    arm->commanded = 0;
    publish(arm, block);
    publish_stream(arm, stream);
}

void plem_arm_report_overruns(plem_arm *arm, int64_t overruns, int64_t missed, int64_t longest, int64_t total,
                              int64_t window_ms) {
    emit(arm, PLEM_EVENT_OVERRUN, PLEM_CAUSE_OVERRUN, -1, -1, (int)window_ms, 0, (double)overruns, (double)missed,
         (double)longest, (double)total);
}
