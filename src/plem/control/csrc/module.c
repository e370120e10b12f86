/* plem.control._core: the compiled core's functions over structures held in Python-owned buffers.
 *
 * Each structure arrives as a writable, contiguous, 8-byte aligned buffer at least the structure's size (a
 * numpy array of the dtype plem.control.compiled builds from `layout()`); vectors arrive as float64, int32 or
 * uint16 buffers of at least the arm's joint count. Calls are a few microseconds and keep the interpreter lock.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <pthread.h>
#include <stddef.h>
#include <string.h>

#include "master_binding.h"
#include "plem_core.h"
#include "thread.h"

/* Nested structures travel as buffers of their own, which the core takes only 8-byte aligned. */
_Static_assert(offsetof(plem_sim, power) % 8 == 0, "plem_sim.power must be 8-byte aligned");
_Static_assert(offsetof(plem_sim, model) % 8 == 0, "plem_sim.model must be 8-byte aligned");
_Static_assert(offsetof(plem_stream_block, used_session) % 64 == 0,
               "the stream block's core-written fields must start a cache line: the writer's are not on it");

/* A borrowed view of a buffer argument, released by `release`. */
typedef struct { Py_buffer view; int held; } argument;

static void release(argument *args, int count) {
    for (int i = 0; i < count; i++)
        if (args[i].held) PyBuffer_Release(&args[i].view), args[i].held = 0;
}

/* Take `object` as a buffer of at least `size` bytes, aligned to 8, writable when asked. */
static void *take(PyObject *object, argument *arg, Py_ssize_t size, int writable, const char *what) {
    if (PyObject_GetBuffer(object, &arg->view, PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0)) < 0)
        return NULL;
    arg->held = 1;
    if (arg->view.len < size || ((uintptr_t)arg->view.buf & 7u) != 0) {
        PyErr_Format(PyExc_ValueError, "%s: expected an 8-byte aligned buffer of at least %zd bytes, got %zd bytes",
                     what, size, arg->view.len);
        return NULL;
    }
    return arg->view.buf;
}

#define JOINTS(model) ((Py_ssize_t)(model)->dof * (Py_ssize_t)sizeof(double))

static int checked_model(const plem_model *model) {
    if (model->dof < 1 || model->dof > PLEM_MAX_JOINTS) {
        PyErr_Format(PyExc_ValueError, "model: dof %d outside 1..%d", model->dof, PLEM_MAX_JOINTS);
        return 0;
    }
    return 1;
}

static PyObject *dynamics_call(PyObject *args, int which) {
    PyObject *objects[5] = {NULL};
    argument held[5] = {{{0}, 0}};
    int inputs = which == 1 ? 2 : 4;   /* gravity: model, q, out; the others: model, x, y, z, out */
    if (!PyArg_UnpackTuple(args, "dynamics", inputs + 1, inputs + 1, &objects[0], &objects[1], &objects[2],
                           &objects[3], &objects[4]))
        return NULL;
    plem_model *model = take(objects[0], &held[0], sizeof(plem_model), 0, "model");
    PyObject *result = NULL;
    if (model && checked_model(model)) {
        double *vectors[4] = {NULL};
        int ok = 1;
        for (int i = 1; i <= inputs && ok; i++)
            ok = (vectors[i - 1] = take(objects[i], &held[i], JOINTS(model), i == inputs, "vector")) != NULL;
        if (ok) {
            if (which == 0) plem_inverse_dynamics(model, vectors[0], vectors[1], vectors[2], vectors[3]);
            else if (which == 1) plem_gravity(model, vectors[0], vectors[1]);
            else plem_forward_dynamics(model, vectors[0], vectors[1], vectors[2], vectors[3]);
            result = Py_NewRef(Py_None);
        }
    }
    release(held, 5);
    return result;
}

/* follow(state, target_position, target_velocity, speed, max_velocity, max_acceleration, max_jerk, low, high, dt):
 * one joint's (p, v, a) in a float64 buffer of 3, one follower cycle on; speed is the share of max_velocity not to
 * pass, a NaN target_position none. */
static PyObject *follow(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *object;
    double target, velocity, speed, max_velocity, max_acceleration, max_jerk, low, high, dt;
    if (!PyArg_ParseTuple(args, "Oddddddddd", &object, &target, &velocity, &speed, &max_velocity, &max_acceleration,
                          &max_jerk, &low, &high, &dt))
        return NULL;
    argument held = {{0}, 0};
    double *state = take(object, &held, 3 * sizeof(double), 1, "state");
    plem_follow_targets targets = {.target_position = isfinite(target) ? &target : NULL, .target_velocity = &velocity,
                                   .max_velocity = &max_velocity, .max_acceleration = &max_acceleration,
                                   .max_jerk = &max_jerk, .share = 1.0, .speed = speed, .low = &low, .high = &high};
    if (state) plem_follow(1, &state[0], &state[1], &state[2], &targets, dt);
    release(&held, 1);
    return state ? Py_NewRef(Py_None) : NULL;
}

static PyObject *inverse_dynamics(PyObject *self, PyObject *args) { (void)self; return dynamics_call(args, 0); }
static PyObject *gravity(PyObject *self, PyObject *args) { (void)self; return dynamics_call(args, 1); }
static PyObject *forward_dynamics(PyObject *self, PyObject *args) { (void)self; return dynamics_call(args, 2); }

static PyObject *motion_sample(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objects[5];
    int segments, dof;
    double t;
    if (!PyArg_ParseTuple(args, "OOOiidOO", &objects[0], &objects[1], &objects[2], &segments, &dof, &t,
                          &objects[3], &objects[4]))
        return NULL;
    if (segments < 0 || dof < 1 || dof > PLEM_MAX_JOINTS)
        return PyErr_Format(PyExc_ValueError, "motion_sample: %d segments of %d joints", segments, dof);
    argument held[5] = {{{0}, 0}, {{0}, 0}, {{0}, 0}, {{0}, 0}, {{0}, 0}};
    Py_ssize_t row = dof * (Py_ssize_t)sizeof(double);
    plem_motion motion = {NULL, NULL, NULL, segments, dof, 0};
    int32_t *cursor = NULL;
    double *out = NULL;
    PyObject *result = NULL;
    if ((motion.knots = take(objects[0], &held[0], (segments + 1) * (Py_ssize_t)sizeof(double), 0, "knots"))
        && (motion.coefficients = take(objects[1], &held[1], segments * PLEM_ORDER * row, 0, "coefficients"))
        && (motion.final = take(objects[2], &held[2], 3 * row, 0, "final"))
        && (cursor = take(objects[3], &held[3], sizeof(int32_t), 1, "cursor"))
        && (out = take(objects[4], &held[4], 3 * row, 1, "out"))) {
        motion.cursor = *cursor;
        result = PyBool_FromLong(plem_motion_sample(&motion, t, out));
        *cursor = motion.cursor;
    }
    release(held, 5);
    return result;
}

static PyObject *plan_stop(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objects[8];
    if (!PyArg_UnpackTuple(args, "plan_stop", 8, 8, &objects[0], &objects[1], &objects[2], &objects[3], &objects[4],
                           &objects[5], &objects[6], &objects[7]))
        return NULL;
    argument held[8] = {{{0}, 0}};
    double *arrays[8] = {NULL};
    argument first = {{0}, 0};
    if (PyObject_GetBuffer(objects[0], &first.view, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    Py_ssize_t dof = first.view.len / (Py_ssize_t)sizeof(double);
    PyBuffer_Release(&first.view);
    if (dof < 1 || dof > PLEM_MAX_JOINTS) return PyErr_Format(PyExc_ValueError, "plan_stop: %zd joints", dof);
    Py_ssize_t row = dof * (Py_ssize_t)sizeof(double);
    const Py_ssize_t sizes[8] = {row, row, row, row, row, (PLEM_STOP_SEGMENTS + 1) * (Py_ssize_t)sizeof(double),
                                 PLEM_STOP_SEGMENTS * PLEM_ORDER * row, 3 * row};
    static const char *names[8] = {"p", "v", "a", "max_acceleration", "max_jerk", "knots", "coefficients", "final"};
    int ok = 1;
    for (int i = 0; i < 8 && ok; i++) ok = (arrays[i] = take(objects[i], &held[i], sizes[i], i >= 5, names[i])) != NULL;
    PyObject *result = ok ? PyLong_FromLong(plem_plan_stop((int)dof, arrays[0], arrays[1], arrays[2], arrays[3],
                                                             arrays[4], arrays[5], arrays[6], arrays[7])) : NULL;
    release(held, 8);
    return result;
}

static plem_sim *take_sim(PyObject *object, argument *arg) {
    plem_sim *sim = take(object, arg, sizeof(plem_sim), 1, "sim");
    if (sim && (sim->dof < 1 || sim->dof > PLEM_MAX_JOINTS || sim->power.dof != sim->dof
                || (sim->dynamics && sim->model.dof != sim->dof))) {
        PyErr_SetString(PyExc_ValueError, "sim: joint counts of the arm, its power sequencer and its model disagree");
        return NULL;
    }
    return sim;
}

static int sim_write_step(plem_sim *sim) { plem_sim_write(sim); return -1; }
static int sim_power_off_step(plem_sim *sim) { plem_sim_power_off(sim); return -1; }

/* One of the simulated arm's single-argument operations: True/False for those that answer, None for the rest (-1). */
static PyObject *on_sim(PyObject *object, int (*operation)(plem_sim *)) {
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    PyObject *result = NULL;
    if (sim) {
        int answer = operation(sim);
        result = answer < 0 ? Py_NewRef(Py_None) : PyBool_FromLong(answer);
    }
    release(&arg, 1);
    return result;
}

static PyObject *sim_read(PyObject *self, PyObject *object) { (void)self; return on_sim(object, plem_sim_read); }
static PyObject *sim_write(PyObject *self, PyObject *object) { (void)self; return on_sim(object, sim_write_step); }
static PyObject *sim_quick_stop(PyObject *self, PyObject *object) {
    (void)self;
    return on_sim(object, plem_sim_quick_stop);
}
static PyObject *sim_power_off(PyObject *self, PyObject *object) {
    (void)self;
    return on_sim(object, sim_power_off_step);
}

static PyObject *sim_serve(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *sim_object, *words_object;
    if (!PyArg_ParseTuple(args, "OO", &sim_object, &words_object)) return NULL;
    argument held[2] = {{{0}, 0}, {{0}, 0}};
    plem_sim *sim = take_sim(sim_object, &held[0]);
    uint16_t *words = sim ? take(words_object, &held[1], sim->dof * (Py_ssize_t)sizeof(uint16_t), 0,
                                 "controlwords") : NULL;
    if (words) plem_sim_serve(sim, words);
    release(held, 2);
    return words ? Py_NewRef(Py_None) : NULL;
}

static PyObject *sim_fault(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *object;
    int drive, code, latched;
    if (!PyArg_ParseTuple(args, "Oiip", &object, &drive, &code, &latched)) return NULL;
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    int ok = sim != NULL;
    if (ok && (drive < 0 || drive >= sim->dof || code < 0 || code > 0xFFFF)) {
        PyErr_Format(PyExc_ValueError, "sim_fault: drive %d or error code %d out of range", drive, code);
        ok = 0;
    }
    if (ok) plem_sim_fault(sim, drive, (uint16_t)code, latched);
    release(&arg, 1);
    return ok ? Py_NewRef(Py_None) : NULL;
}

static plem_power *take_power(PyObject *object, argument *arg) {
    plem_power *power = take(object, arg, sizeof(plem_power), 1, "power");
    if (power && (power->dof < 0 || power->dof > PLEM_MAX_JOINTS)) {
        PyErr_Format(PyExc_ValueError, "power: dof %d outside 0..%d", power->dof, PLEM_MAX_JOINTS);
        return NULL;
    }
    return power;
}

static PyObject *power_init(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *object;
    int dof;
    if (!PyArg_ParseTuple(args, "Oi", &object, &dof)) return NULL;
    if (dof < 0 || dof > PLEM_MAX_JOINTS) return PyErr_Format(PyExc_ValueError, "power_init: dof %d", dof);
    argument arg = {{0}, 0};
    plem_power *power = take(object, &arg, sizeof(plem_power), 1, "power");
    if (power) plem_power_init(power, dof);
    release(&arg, 1);
    return power ? Py_NewRef(Py_None) : NULL;
}

static PyObject *power_request(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *object;
    int state;
    if (!PyArg_ParseTuple(args, "Oi", &object, &state)) return NULL;
    if (state < PLEM_SWITCH_ON_DISABLED || state > PLEM_OPERATION_ENABLED)
        return PyErr_Format(PyExc_ValueError, "power_request: %d is not a state a controlword can hold", state);
    argument arg = {{0}, 0};
    plem_power *power = take_power(object, &arg);
    if (power) plem_power_request(power, state);
    release(&arg, 1);
    return power ? Py_NewRef(Py_None) : NULL;
}

static PyObject *power_request_reset(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_power *power = take_power(object, &arg);
    if (power) plem_power_request_reset(power);
    release(&arg, 1);
    return power ? Py_NewRef(Py_None) : NULL;
}

static PyObject *power_master_lost(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_power *power = take_power(object, &arg);
    if (power) plem_power_master_lost(power);
    release(&arg, 1);
    return power ? Py_NewRef(Py_None) : NULL;
}

static PyObject *power_commands(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objects[3];
    if (!PyArg_UnpackTuple(args, "power_commands", 3, 3, &objects[0], &objects[1], &objects[2])) return NULL;
    argument held[3] = {{{0}, 0}, {{0}, 0}, {{0}, 0}};
    plem_power *power = take_power(objects[0], &held[0]);
    int32_t *seen = power ? take(objects[1], &held[1], power->dof * (Py_ssize_t)sizeof(int32_t), 0, "seen") : NULL;
    uint16_t *out = seen ? take(objects[2], &held[2], power->dof * (Py_ssize_t)sizeof(uint16_t), 1, "out") : NULL;
    if (out) plem_power_commands(power, seen, out);
    release(held, 3);
    return out ? Py_NewRef(Py_None) : NULL;
}

static PyObject *decode_statusword(PyObject *self, PyObject *args) {
    (void)self;
    unsigned int word;
    if (!PyArg_ParseTuple(args, "I", &word)) return NULL;
    return PyLong_FromLong(plem_decode_statusword((uint16_t)word));
}

static PyObject *statusword_of(PyObject *self, PyObject *args) {
    (void)self;
    int state;
    if (!PyArg_ParseTuple(args, "i", &state)) return NULL;
    return PyLong_FromLong(plem_statusword_of(state));
}

static PyObject *next_controlword(PyObject *self, PyObject *args) {
    (void)self;
    int state, target;
    unsigned int previous;
    if (!PyArg_ParseTuple(args, "iiI", &state, &target, &previous)) return NULL;
    return PyLong_FromLong(plem_next_controlword(state, target, (uint16_t)previous));
}

static PyObject *drive_transition(PyObject *self, PyObject *args) {
    (void)self;
    int state;
    unsigned int controlword, previous;
    if (!PyArg_ParseTuple(args, "iII", &state, &controlword, &previous)) return NULL;
    return PyLong_FromLong(plem_drive_transition(state, (uint16_t)controlword, (uint16_t)previous));
}


/* ---- the arm's cycle: a Core holds the buffers one arm's cycles work on ------------------------------------ */

typedef struct {
    PyObject_HEAD
    argument arm, header, values, slab, sim, raw, stats, stream;
    PyObject *master_object;         /* the Master the bus exchanges through, kept alive while held */
    plem_bus bus;
    plem_slab slab_view;
    plem_state_block block;
    plem_raw_ring raw_view;
    plem_loop loop;
    pthread_t thread;
    int running;
} Core;

/* Stop the real-time thread and wait for it, without the interpreter lock (it never needs it). */
static void core_stop_thread(Core *core) {
    if (!core->running) return;
    atomic_store_explicit(&core->loop.stop, 1, memory_order_release);
    Py_BEGIN_ALLOW_THREADS
    pthread_join(core->thread, NULL);
    Py_END_ALLOW_THREADS
    core->running = 0;
    if (core->bus.master) core->bus.master->in_cycle = 0;
}

static void core_release(Core *core) {
    core_stop_thread(core);
    argument *held[8] = {&core->arm,  &core->header, &core->values, &core->slab,
                         &core->sim,  &core->raw,    &core->stats,  &core->stream};
    for (int i = 0; i < 8; i++) release(held[i], 1);
    core->bus = (plem_bus){NULL, NULL};
    Py_CLEAR(core->master_object);
}

static void core_dealloc(Core *core) {
    core_release(core);
    Py_TYPE(core)->tp_free((PyObject *)core);
}

/* The rt_raw ring: a plem ring (magic, version 1, drop-oldest) whose slots hold one record of this arm. */
static int take_raw(Core *core, PyObject *raw, int dof) {
    uint8_t *base = take(raw, &core->raw, 64, 1, "raw ring");
    if (!base) return 0;
    uint32_t version, slot_bytes, slots, flags;
    memcpy(&version, base + 8, 4), memcpy(&slot_bytes, base + 12, 4), memcpy(&slots, base + 16, 4);
    memcpy(&flags, base + 20, 4);
    Py_ssize_t record = (8 + 6 * (Py_ssize_t)dof) * (Py_ssize_t)sizeof(double);
    if (memcmp(base, "PLEMRING", 8) != 0 || version != 1 || flags != 0 || slots == 0 || slot_bytes < record
        || 64 + (Py_ssize_t)slots * (16 + (Py_ssize_t)slot_bytes) > core->raw.view.len) {
        PyErr_SetString(PyExc_ValueError, "raw ring: not a drop-oldest plem ring with room for this arm's record");
        return 0;
    }
    core->raw_view = (plem_raw_ring){base, slot_bytes, slots};
    return 1;
}

static int core_init(Core *core, PyObject *args, PyObject *kwargs) {
    static char *keywords[] = {"arm", "header", "values", "slab", "sim", "raw", "stats", "master", "stream", NULL};
    PyObject *arm, *header, *values, *slab, *sim = Py_None, *raw = Py_None, *stats = Py_None, *master = Py_None;
    PyObject *stream = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOO|OOOOO", keywords, &arm, &header, &values, &slab, &sim, &raw,
                                     &stats, &master, &stream))
        return -1;
    core_release(core);
    plem_arm *a = take(arm, &core->arm, sizeof(plem_arm), 1, "arm");
    if (!a) goto fail;
    int dof = a->settings.dof;
    if (dof < 1 || dof > PLEM_MAX_JOINTS || a->model.dof != dof) {
        PyErr_Format(PyExc_ValueError, "arm: dof %d and its model's %d must agree, 1..%d", dof, a->model.dof,
                     PLEM_MAX_JOINTS);
        goto fail;
    }
    if (!(core->block.header = take(header, &core->header, 6 * sizeof(int64_t), 1, "state header"))) goto fail;
    if (!(core->block.values = take(values, &core->values, 6 * dof * (Py_ssize_t)sizeof(double), 1, "state values")))
        goto fail;
    if (!(core->slab_view.base = take(slab, &core->slab, 64, 0, "slab"))) goto fail;
    core->slab_view.size = core->slab.view.len;
    if (sim != Py_None) {
        plem_sim *s = take(sim, &core->sim, sizeof(plem_sim), 1, "sim");
        if (!s) goto fail;
        if (s->dof != dof) {
            PyErr_Format(PyExc_ValueError, "sim: %d joints for an arm of %d", s->dof, dof);
            goto fail;
        }
        core->bus.sim = s;
    }
    if (master != Py_None) {
        plem_master *m = plem_master_of(master);
        if (!m) goto fail;
        if (sim != Py_None || m->dof != dof) {
            PyErr_Format(PyExc_ValueError, "master: prepared for %d drives for an arm of %d, and no sim beside it",
                         m->dof, dof);
            goto fail;
        }
        core->bus.master = m;
        core->master_object = Py_NewRef(master);
    }
    if (raw != Py_None && !take_raw(core, raw, dof)) goto fail;
    if (stats != Py_None && !take(stats, &core->stats, sizeof(plem_stats), 1, "stats")) goto fail;
    if (stream != Py_None && !take(stream, &core->stream, sizeof(plem_stream_block), 1, "stream")) goto fail;
    return 0;
fail:
    core_release(core);
    return -1;
}

static int core_ready(Core *core) {
    if (!core->arm.held) {
        PyErr_SetString(PyExc_RuntimeError, "the core holds no arm (it was closed)");
        return 0;
    }
    if (core->running) {
        PyErr_SetString(PyExc_RuntimeError, "the core's real-time thread runs the cycles");
        return 0;
    }
    return 1;
}

static plem_stream_block *stream_of(Core *core) { return core->stream.held ? core->stream.view.buf : NULL; }

static PyObject *core_cycle(Core *core, PyObject *unused) {
    (void)unused;
    if (!core_ready(core)) return NULL;
    if (core->bus.master && (!core->bus.master->open || core->bus.master->in_cycle))
        return PyErr_Format(PyExc_RuntimeError, "the core's EtherCAT master is closed or cycled by another core");
    plem_arm_cycle(core->arm.view.buf, &core->bus, &core->slab_view, &core->block, stream_of(core));
    Py_RETURN_NONE;
}

static PyObject *core_record_raw(Core *core, PyObject *args) {
    long long latency, compute;
    if (!PyArg_ParseTuple(args, "LL", &latency, &compute)) return NULL;
    if (!core_ready(core)) return NULL;
    if (core->raw.held)
        plem_raw_write(&core->raw_view, &core->block, ((plem_arm *)core->arm.view.buf)->settings.dof, latency, compute,
                       ((plem_arm *)core->arm.view.buf)->override.factor);
    Py_RETURN_NONE;
}

static PyObject *core_fault(Core *core, PyObject *args) {
    int cause;
    double v0 = 0.0, v1 = 0.0;
    if (!PyArg_ParseTuple(args, "i|dd", &cause, &v0, &v1)) return NULL;
    if (!core_ready(core)) return NULL;
    plem_arm_fault(core->arm.view.buf, cause, v0, v1);
    Py_RETURN_NONE;
}

static PyObject *core_start(Core *core, PyObject *args, PyObject *kwargs) {
    static char *keywords[] = {"period_ns", "priority", "cpus", "max_consecutive_overruns", "window_ns", NULL};
    long long period, window;
    unsigned long long cpus;
    int priority, overruns;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "LiKiL", keywords, &period, &priority, &cpus, &overruns, &window))
        return NULL;
    if (!core_ready(core)) return NULL;
    if (!core->stats.held) return PyErr_Format(PyExc_RuntimeError, "the core was given no statistics to keep");
    if (period <= 0 || window <= 0 || overruns < 1 || priority < 0 || priority > 99)
        return PyErr_Format(PyExc_ValueError, "start: period %lld ns, window %lld ns, %d overruns, priority %d",
                            period, window, overruns, priority);
    plem_master *master = core->bus.master;
    if (master && (!master->open || master->in_cycle))
        return PyErr_Format(PyExc_RuntimeError, "the core's EtherCAT master is closed or cycled by another core");
    core->loop = (plem_loop){core->arm.view.buf, core->bus, &core->slab_view, &core->block, stream_of(core),
                             core->raw.held ? &core->raw_view : NULL, core->stats.view.buf, period, window, cpus,
                             priority, overruns, 0};
    if (master) master->in_cycle = 1;
    int error = pthread_create(&core->thread, NULL, plem_loop_run, &core->loop);
    if (error) {
        if (master) master->in_cycle = 0;
        return PyErr_Format(PyExc_OSError, "the real-time thread could not be created: %s", strerror(error));
    }
    core->running = 1;
    Py_RETURN_NONE;
}

static PyObject *core_stop(Core *core, PyObject *unused) {
    (void)unused;
    core_stop_thread(core);
    Py_RETURN_NONE;
}

static PyObject *core_running(Core *core, void *closure) {
    (void)closure;
    return PyBool_FromLong(core->running);
}

static PyObject *core_close(Core *core, PyObject *unused) {
    (void)unused;
    core_release(core);
    Py_RETURN_NONE;
}

static PyGetSetDef CORE_GETSET[] = {
    {"running", (getter)core_running, NULL, "The real-time thread runs the cycles.", NULL},
    {NULL, NULL, NULL, NULL, NULL}};

static PyMethodDef CORE_METHODS[] = {
    {"cycle", (PyCFunction)core_cycle, METH_NOARGS, "Run one cycle of the arm now, in the calling thread."},
    {"record_raw", (PyCFunction)core_record_raw, METH_VARARGS,
     "record_raw(latency_ns, compute_ns): the rt_raw record of the cycle just run (when a raw ring is held)."},
    {"start", (PyCFunction)(void (*)(void))core_start, METH_VARARGS | METH_KEYWORDS,
     "start(period_ns, priority, cpus, max_consecutive_overruns, window_ns): the real-time thread runs the cycles."},
    {"stop", (PyCFunction)core_stop, METH_NOARGS, "Stop the real-time thread after its current cycle and join it."},
    {"close", (PyCFunction)core_close, METH_NOARGS,
     "Stop the thread and let go of every buffer (shared memory may then be unmapped)."},
    {"fault", (PyCFunction)core_fault, METH_VARARGS, "fault(cause, value0=0, value1=0): fault from outside the cycle."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject CORE_TYPE = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "plem.control._core.Core",
    .tp_basicsize = sizeof(Core),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Core(arm, header, values, slab, sim=None, raw=None, stats=None, master=None): one arm's cycle over "
              "the buffers it holds, on the simulated arm, an EtherCAT master or process data the caller exchanges, "
              "run by the caller or by the core's own real-time thread.",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)core_init,
    .tp_dealloc = (destructor)core_dealloc,
    .tp_methods = CORE_METHODS,
    .tp_getset = CORE_GETSET,
};

static PyObject *arm_init(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_arm *arm = take(object, &arg, sizeof(plem_arm), 1, "arm");
    if (arm && (arm->settings.dof < 1 || arm->settings.dof > PLEM_MAX_JOINTS)) {
        PyErr_Format(PyExc_ValueError, "arm: dof %d outside 1..%d", arm->settings.dof, PLEM_MAX_JOINTS);
        arm = NULL;
    }
    if (arm) plem_arm_init(arm);
    release(&arg, 1);
    return arm ? Py_NewRef(Py_None) : NULL;
}

/* ---- the layout table ---------------------------------------------------------------------------------- */

typedef struct { const char *name; size_t offset, size; } field;

#define FIELD(type, member) {#member, offsetof(type, member), sizeof(((type *)0)->member)}

static const field MODEL_FIELDS[] = {
    FIELD(plem_model, dof), FIELD(plem_model, gravity), FIELD(plem_model, parent), FIELD(plem_model, kind),
    FIELD(plem_model, arm_index), FIELD(plem_model, axis), FIELD(plem_model, rotation),
    FIELD(plem_model, translation), FIELD(plem_model, mass), FIELD(plem_model, com), FIELD(plem_model, inertia),
    {NULL, 0, 0}};

static const field POWER_FIELDS[] = {
    FIELD(plem_power, dof), FIELD(plem_power, wanted), FIELD(plem_power, reset), FIELD(plem_power, sent),
    {NULL, 0, 0}};

static const field SIM_FIELDS[] = {
    FIELD(plem_sim, dof), FIELD(plem_sim, dynamics), FIELD(plem_sim, dt), FIELD(plem_sim, omega),
    FIELD(plem_sim, follow), FIELD(plem_sim, deceleration), FIELD(plem_sim, counts), FIELD(plem_sim, raw_zero),
    FIELD(plem_sim, friction), FIELD(plem_sim, effort), FIELD(plem_sim, lower), FIELD(plem_sim, upper),
    FIELD(plem_sim, max_error), FIELD(plem_sim, q), FIELD(plem_sim, v), FIELD(plem_sim, tau),
    FIELD(plem_sim, external), FIELD(plem_sim, push), FIELD(plem_sim, push_point), FIELD(plem_sim, push_body),
    FIELD(plem_sim, payload_pending), FIELD(plem_sim, payload_body), FIELD(plem_sim, stop_q), FIELD(plem_sim, stop_v), FIELD(plem_sim, spike),
    FIELD(plem_sim, stuck), FIELD(plem_sim, latched), FIELD(plem_sim, stopping), FIELD(plem_sim, state),
    FIELD(plem_sim, statusword), FIELD(plem_sim, error_code), FIELD(plem_sim, controlword),
    FIELD(plem_sim, digital_inputs), FIELD(plem_sim, lost),
    FIELD(plem_sim, answered),
    FIELD(plem_sim, lost_reads), FIELD(plem_sim, lost_frames), FIELD(plem_sim, io_target_position),
    FIELD(plem_sim, io_velocity_offset), FIELD(plem_sim, io_torque_offset), FIELD(plem_sim, io_mode),
    FIELD(plem_sim, io_position), FIELD(plem_sim, io_velocity), FIELD(plem_sim, io_torque),
    FIELD(plem_sim, io_statusword), FIELD(plem_sim, io_error_code), FIELD(plem_sim, power),
    FIELD(plem_sim, scratch), FIELD(plem_sim, model), {NULL, 0, 0}};


static const field SETTINGS_FIELDS[] = {
    FIELD(plem_settings, dof), FIELD(plem_settings, bus), FIELD(plem_settings, dt),
    FIELD(plem_settings, tracking_tolerance), FIELD(plem_settings, velocity_margin),
    FIELD(plem_settings, position_margin), FIELD(plem_settings, standstill_velocity),
    FIELD(plem_settings, command_tolerance), FIELD(plem_settings, enable_timeout_cycles),
    FIELD(plem_settings, counts_per_radian), FIELD(plem_settings, offsets), FIELD(plem_settings, min_position),
    FIELD(plem_settings, max_position), FIELD(plem_settings, max_velocity), FIELD(plem_settings, max_acceleration),
    FIELD(plem_settings, max_jerk), FIELD(plem_settings, max_effort), FIELD(plem_settings, damping),
    FIELD(plem_settings, friction), FIELD(plem_settings, contact_threshold), {NULL, 0, 0}};

static const field BASIS_FIELDS[] = {
    FIELD(plem_basis, sequence), FIELD(plem_basis, generation), FIELD(plem_basis, slot), FIELD(plem_basis, segments),
    FIELD(plem_basis, start_cycle), FIELD(plem_basis, time), FIELD(plem_basis, rate), FIELD(plem_basis, ramping),
    FIELD(plem_basis, hold_position), {NULL, 0, 0}};

static const field OVERRIDE_FIELDS[] = {
    FIELD(plem_override, target), FIELD(plem_override, factor), FIELD(plem_override, rate), FIELD(plem_override, time),
    FIELD(plem_override, peaks), {NULL, 0, 0}};

static const field TERM_FIELDS[] = {
    FIELD(plem_term, op), FIELD(plem_term, measure), FIELD(plem_term, index), FIELD(plem_term, threshold),
    {NULL, 0, 0}};

static const field REACTION_FIELDS[] = {
    FIELD(plem_reaction, token), FIELD(plem_reaction, motion), FIELD(plem_reaction, armed), FIELD(plem_reaction, terms),
    FIELD(plem_reaction, action), FIELD(plem_reaction, once), FIELD(plem_reaction, term), FIELD(plem_reaction, target),
    {NULL, 0, 0}};

static const field ARMED_FIELDS[] = {
    FIELD(plem_armed, table), FIELD(plem_armed, start), FIELD(plem_armed, comparisons),
    {NULL, 0, 0}};

static const field COMPARISON_FIELDS[] = {
    FIELD(plem_comparison, holds_if), FIELD(plem_comparison, measure), FIELD(plem_comparison, index),
    FIELD(plem_comparison, threshold), {NULL, 0, 0}};

static const field PROGRAM_FIELDS[] = {
    FIELD(plem_program, slot), FIELD(plem_program, comparison), FIELD(plem_program, uses),
    FIELD(plem_program, bound), FIELD(plem_program, was_true), {NULL, 0, 0}};

static const field STREAM_FIELDS[] = {
    FIELD(plem_stream, session), FIELD(plem_stream, timeout_cycles), FIELD(plem_stream, last_cycle),
    FIELD(plem_stream, last_count), FIELD(plem_stream, last_stamp), FIELD(plem_stream, feed_until),
    FIELD(plem_stream, kind), FIELD(plem_stream, timed_out), FIELD(plem_stream, internal), FIELD(plem_stream, target),
    FIELD(plem_stream, feed),
    {NULL, 0, 0}};

static const field STREAM_BLOCK_FIELDS[] = {
    FIELD(plem_stream_block, sequence), FIELD(plem_stream_block, session), FIELD(plem_stream_block, count),
    FIELD(plem_stream_block, kind), FIELD(plem_stream_block, stamp_ns), FIELD(plem_stream_block, checksum),
    FIELD(plem_stream_block, target), FIELD(plem_stream_block, used_session), FIELD(plem_stream_block, used_count),
    FIELD(plem_stream_block, used_cycle), FIELD(plem_stream_block, latency_ns), FIELD(plem_stream_block, state),
    FIELD(plem_stream_block, speed_override), FIELD(plem_stream_block, override_target),
    FIELD(plem_stream_block, external), FIELD(plem_stream_block, wrench), {NULL, 0, 0}};

static const field RING_FIELDS[] = {
    FIELD(plem_ring, head), FIELD(plem_ring, tail), FIELD(plem_ring, dropped), {NULL, 0, 0}};

static const field COMMAND_FIELDS[] = {
    FIELD(plem_command, token), FIELD(plem_command, op), FIELD(plem_command, mode), FIELD(plem_command, slot),
    FIELD(plem_command, segments), FIELD(plem_command, basis), FIELD(plem_command, activation),
    FIELD(plem_command, goal), FIELD(plem_command, has_path), FIELD(plem_command, has_goal),
    FIELD(plem_command, goal_time), FIELD(plem_command, stopped_velocity), FIELD(plem_command, path),
    FIELD(plem_command, goal_tolerance), FIELD(plem_command, peaks), FIELD(plem_command, value), FIELD(plem_command, body),
    FIELD(plem_command, cycles), {NULL, 0, 0}};

static const field OUTCOME_FIELDS[] = {
    FIELD(plem_outcome, token), FIELD(plem_outcome, cycle), FIELD(plem_outcome, stage), FIELD(plem_outcome, answer),
    FIELD(plem_outcome, mode), FIELD(plem_outcome, detail), FIELD(plem_outcome, joint), FIELD(plem_outcome, values),
    {NULL, 0, 0}};

static const field EVENT_FIELDS[] = {
    FIELD(plem_event, cycle), FIELD(plem_event, monotonic_ns), FIELD(plem_event, token), FIELD(plem_event, kind),
    FIELD(plem_event, cause), FIELD(plem_event, mode), FIELD(plem_event, previous_mode), FIELD(plem_event, joint),
    FIELD(plem_event, detail), FIELD(plem_event, values), {NULL, 0, 0}};

static const field ARM_FIELDS[] = {
    FIELD(plem_arm, settings), FIELD(plem_arm, model), FIELD(plem_arm, io_position), FIELD(plem_arm, io_velocity),
    FIELD(plem_arm, io_torque), FIELD(plem_arm, io_statusword), FIELD(plem_arm, io_error_code),
    FIELD(plem_arm, io_target_position), FIELD(plem_arm, io_velocity_offset), FIELD(plem_arm, io_torque_offset),
    FIELD(plem_arm, io_mode), FIELD(plem_arm, io_digital_inputs), FIELD(plem_arm, io_inputs_reported),
    FIELD(plem_arm, io_answered), FIELD(plem_arm, power_wanted),
    FIELD(plem_arm, power_requests),
    FIELD(plem_arm, power_resets), FIELD(plem_arm, power), FIELD(plem_arm, cycle), FIELD(plem_arm, mode),
    FIELD(plem_arm, fault_cause), FIELD(plem_arm, communication_ok), FIELD(plem_arm, have_previous),
    FIELD(plem_arm, braking), FIELD(plem_arm, work), FIELD(plem_arm, previous_position),
    FIELD(plem_arm, previous_acceleration), FIELD(plem_arm, torque), FIELD(plem_arm, reach), FIELD(plem_arm, active),
    FIELD(plem_arm, active_ended), FIELD(plem_arm, active_slot), FIELD(plem_arm, active_segments),
    FIELD(plem_arm, active_token), FIELD(plem_arm, last_start), FIELD(plem_arm, active_start_cycle),
    FIELD(plem_arm, settle_deadline),
    FIELD(plem_arm, active_cursor), FIELD(plem_arm, active_has_path), FIELD(plem_arm, active_has_goal),
    FIELD(plem_arm, active_goal_time), FIELD(plem_arm, active_stopped_velocity), FIELD(plem_arm, active_path),
    FIELD(plem_arm, active_goal), FIELD(plem_arm, active_final), FIELD(plem_arm, pending),
    FIELD(plem_arm, pending_target), FIELD(plem_arm, pending_deadline), FIELD(plem_arm, pending_token),
    FIELD(plem_arm, pending_enable_sent), FIELD(plem_arm, stop_knots), FIELD(plem_arm, stop_coefficients),
    FIELD(plem_arm, stop_final), FIELD(plem_arm, stop_segments), FIELD(plem_arm, basis), FIELD(plem_arm, override),
    FIELD(plem_arm, stream), FIELD(plem_arm, feeling), FIELD(plem_arm, reacting), FIELD(plem_arm, unsettled), FIELD(plem_arm, commanded),
    FIELD(plem_arm, external), FIELD(plem_arm, wrench),
    FIELD(plem_arm, reactions), FIELD(plem_arm, program),
    FIELD(plem_arm, commands_index), FIELD(plem_arm, commands), FIELD(plem_arm, outcomes_index),
    FIELD(plem_arm, outcomes), FIELD(plem_arm, events_index), FIELD(plem_arm, events), {NULL, 0, 0}};

static const field SERIES_FIELDS[] = {
    FIELD(plem_series, count), FIELD(plem_series, total_ns), FIELD(plem_series, min_ns), FIELD(plem_series, max_ns),
    FIELD(plem_series, histogram), FIELD(plem_series, window), {NULL, 0, 0}};

static const field STATS_FIELDS[] = {
    FIELD(plem_stats, cycles), FIELD(plem_stats, overruns), FIELD(plem_stats, missed_periods),
    FIELD(plem_stats, consecutive_overruns), FIELD(plem_stats, policy), FIELD(plem_stats, priority),
    FIELD(plem_stats, sched_error), FIELD(plem_stats, affinity_error), FIELD(plem_stats, cpus),
    FIELD(plem_stats, latency), FIELD(plem_stats, compute), {NULL, 0, 0}};

static const field MASTER_STATUS_FIELDS[] = {
    FIELD(plem_master_status, exchanges), FIELD(plem_master_status, lost_frames),
    FIELD(plem_master_status, working_counter_errors), FIELD(plem_master_status, bad_cycles),
    FIELD(plem_master_status, working_counter), FIELD(plem_master_status, expected_working_counter),
    FIELD(plem_master_status, communication_ok), FIELD(plem_master_status, exchange), {NULL, 0, 0}};

typedef struct { const char *name; long value; } constant;

#define CONSTANT(name) {#name, name}

static const constant CONSTANTS[] = {
    CONSTANT(PLEM_IDLE), CONSTANT(PLEM_HOLD), CONSTANT(PLEM_TRAJECTORY), CONSTANT(PLEM_FREE_DRIVE),
    CONSTANT(PLEM_FAULTED), CONSTANT(PLEM_OP_SET_MODE), CONSTANT(PLEM_OP_START), CONSTANT(PLEM_OP_STOP),
    CONSTANT(PLEM_OP_RESET), CONSTANT(PLEM_ACCEPTED), CONSTANT(PLEM_REJECTED), CONSTANT(PLEM_FINISHED),
    CONSTANT(PLEM_ANSWER_MODE), CONSTANT(PLEM_ANSWER_DONE), CONSTANT(PLEM_ANSWER_NOT_HOLDING),
    CONSTANT(PLEM_ANSWER_STALE), CONSTANT(PLEM_ANSWER_MODE_PENDING), CONSTANT(PLEM_ANSWER_TRANSITION),
    CONSTANT(PLEM_ANSWER_MOVING), CONSTANT(PLEM_ANSWER_ENABLE_TIMEOUT), CONSTANT(PLEM_ANSWER_RESET_NO_BUS),
    CONSTANT(PLEM_ANSWER_FAULTED), CONSTANT(PLEM_ANSWER_SUCCEEDED), CONSTANT(PLEM_ANSWER_GOAL_VIOLATED),
    CONSTANT(PLEM_ANSWER_PATH_VIOLATED), CONSTANT(PLEM_ANSWER_FAULT_ABORTED), CONSTANT(PLEM_ANSWER_PREEMPTED),
    CONSTANT(PLEM_ANSWER_CANCELED), CONSTANT(PLEM_ANSWER_INVALID_SLOT), CONSTANT(PLEM_ANSWER_UNKNOWN_OP),
    CONSTANT(PLEM_ANSWER_STREAMING), CONSTANT(PLEM_ANSWER_STREAM_TIMED_OUT), CONSTANT(PLEM_ANSWER_INVALID_VALUE),
    CONSTANT(PLEM_OP_STREAM), CONSTANT(PLEM_OP_OVERRIDE), CONSTANT(PLEM_OP_REACT), CONSTANT(PLEM_OP_UNREACT),
    CONSTANT(PLEM_OP_PAYLOAD), CONSTANT(PLEM_ANSWER_REACTED), CONSTANT(PLEM_ANSWER_MALFORMED_REACTION),
    CONSTANT(PLEM_EVENT_REACTION),
    CONSTANT(PLEM_CAUSE_CONTACT), CONSTANT(PLEM_CAUSE_REACTION), CONSTANT(PLEM_REACTIONS),
    CONSTANT(PLEM_REACTION_TERMS), CONSTANT(PLEM_CONDITION_COMPARISONS), CONSTANT(PLEM_MEASURE_POSITION),
    CONSTANT(PLEM_MEASURE_VELOCITY),
    CONSTANT(PLEM_MEASURE_EFFORT), CONSTANT(PLEM_MEASURE_EXTERNAL_TORQUE), CONSTANT(PLEM_MEASURE_WRENCH),
    CONSTANT(PLEM_MEASURE_FOLLOWING_ERROR), CONSTANT(PLEM_MEASURE_MOTION_TIME), CONSTANT(PLEM_MEASURE_DRIVE_STATE),
    CONSTANT(PLEM_MEASURE_DIGITAL_INPUT),
    CONSTANT(PLEM_TERM_ABOVE), CONSTANT(PLEM_TERM_BELOW), CONSTANT(PLEM_TERM_EQUAL), CONSTANT(PLEM_TERM_AND),
    CONSTANT(PLEM_TERM_OR), CONSTANT(PLEM_TERM_NOT), CONSTANT(PLEM_REACT_STOP), CONSTANT(PLEM_REACT_HOLD),
    CONSTANT(PLEM_REACT_FREE_DRIVE), CONSTANT(PLEM_REACT_MOVE), CONSTANT(PLEM_REACT_RECORD),
    CONSTANT(PLEM_STREAM_POSITION),
    CONSTANT(PLEM_STREAM_VELOCITY), CONSTANT(PLEM_STREAM_NONE), CONSTANT(PLEM_STREAM_FOLLOWING),
    CONSTANT(PLEM_STREAM_TIMED_OUT), CONSTANT(PLEM_STREAM_SLOT),
    CONSTANT(PLEM_EVENT_MODE_CHANGED), CONSTANT(PLEM_EVENT_FAULT), CONSTANT(PLEM_EVENT_FAULT_CLEARED),
    CONSTANT(PLEM_EVENT_MOTION_STARTED), CONSTANT(PLEM_EVENT_MOTION_FINISHED), CONSTANT(PLEM_EVENT_COMMAND_REJECTED),
    CONSTANT(PLEM_EVENT_WARNING), CONSTANT(PLEM_EVENT_OVERRUN), CONSTANT(PLEM_CAUSE_SET_MODE_IDLE), CONSTANT(PLEM_CAUSE_SET_MODE_FREE_DRIVE),
    CONSTANT(PLEM_CAUSE_SET_MODE_HOLD), CONSTANT(PLEM_CAUSE_DRIVES_ENABLED), CONSTANT(PLEM_CAUSE_MOTION_STARTED),
    CONSTANT(PLEM_CAUSE_MOTION_FINISHED), CONSTANT(PLEM_CAUSE_DRIVE_FAULT), CONSTANT(PLEM_CAUSE_DRIVE_DISABLED),
    CONSTANT(PLEM_CAUSE_ENCODER_JUMP), CONSTANT(PLEM_CAUSE_POSITION_LIMIT), CONSTANT(PLEM_CAUSE_VELOCITY_LIMIT),
    CONSTANT(PLEM_CAUSE_TRACKING_ERROR), CONSTANT(PLEM_CAUSE_COMMUNICATION_LOST),
    CONSTANT(PLEM_CAUSE_INVALID_COMMAND), CONSTANT(PLEM_CAUSE_COMMAND_POSITION),
    CONSTANT(PLEM_CAUSE_COMMAND_VELOCITY), CONSTANT(PLEM_CAUSE_COMMAND_ACCELERATION),
    CONSTANT(PLEM_CAUSE_COMMAND_JERK), CONSTANT(PLEM_CAUSE_OVERRUN), CONSTANT(PLEM_CAUSE_INTERNAL_ERROR),
    CONSTANT(PLEM_CAUSE_RESET), CONSTANT(PLEM_CAUSE_BRAKES_ENGAGED), CONSTANT(PLEM_CAUSE_ENABLE_TIMEOUT),
    CONSTANT(PLEM_STOP_SLOT), CONSTANT(PLEM_COMMAND_SLOTS),
    CONSTANT(PLEM_OUTCOME_SLOTS), CONSTANT(PLEM_EVENT_SLOTS), CONSTANT(PLEM_COMMANDS_PER_CYCLE),
    CONSTANT(PLEM_HISTOGRAM_BINS), CONSTANT(PLEM_WINDOW), CONSTANT(PLEM_RX_CONTROLWORD),
    CONSTANT(PLEM_RX_TARGET_POSITION), CONSTANT(PLEM_RX_VELOCITY_OFFSET), CONSTANT(PLEM_RX_TORQUE_OFFSET),
    CONSTANT(PLEM_RX_MODE), CONSTANT(PLEM_RX_BYTES), CONSTANT(PLEM_TX_STATUSWORD), CONSTANT(PLEM_TX_POSITION),
    CONSTANT(PLEM_TX_VELOCITY), CONSTANT(PLEM_TX_TORQUE), CONSTANT(PLEM_TX_ERROR_CODE), CONSTANT(PLEM_TX_MODE_DISPLAY),
    CONSTANT(PLEM_TX_BYTES), CONSTANT(PLEM_TX_DIGITAL_INPUTS), CONSTANT(PLEM_TX_BYTES_WITH_INPUTS), {NULL, 0}};

static PyObject *constants_dict(void) {
    PyObject *table = PyDict_New();
    for (const constant *c = CONSTANTS; table && c->name; c++) {
        PyObject *value = PyLong_FromLong(c->value);
        if (!value || PyDict_SetItemString(table, c->name, value) < 0) Py_CLEAR(table);
        Py_XDECREF(value);
    }
    return table;
}

static PyObject *fields_dict(const field *fields, size_t size) {
    PyObject *table = Py_BuildValue("{s:n}", "__size__", (Py_ssize_t)size);
    for (const field *f = fields; table && f->name; f++) {
        PyObject *entry = Py_BuildValue("(nn)", (Py_ssize_t)f->offset, (Py_ssize_t)f->size);
        if (!entry || PyDict_SetItemString(table, f->name, entry) < 0) Py_CLEAR(table);
        Py_XDECREF(entry);
    }
    return table;
}

static PyObject *layout(PyObject *self, PyObject *unused) {
    (void)self, (void)unused;
    static const struct { const char *name; const field *fields; size_t size; } STRUCTURES[] = {
        {"plem_model", MODEL_FIELDS, sizeof(plem_model)}, {"plem_power", POWER_FIELDS, sizeof(plem_power)},
        {"plem_sim", SIM_FIELDS, sizeof(plem_sim)}, {"plem_settings", SETTINGS_FIELDS, sizeof(plem_settings)},
        {"plem_basis", BASIS_FIELDS, sizeof(plem_basis)}, {"plem_ring", RING_FIELDS, sizeof(plem_ring)},
        {"plem_override", OVERRIDE_FIELDS, sizeof(plem_override)}, {"plem_stream", STREAM_FIELDS, sizeof(plem_stream)},
        {"plem_term", TERM_FIELDS, sizeof(plem_term)}, {"plem_reaction", REACTION_FIELDS, sizeof(plem_reaction)},
        {"plem_armed", ARMED_FIELDS, sizeof(plem_armed)},
        {"plem_comparison", COMPARISON_FIELDS, sizeof(plem_comparison)},
        {"plem_program", PROGRAM_FIELDS, sizeof(plem_program)},
        {"plem_stream_block", STREAM_BLOCK_FIELDS, sizeof(plem_stream_block)},
        {"plem_command", COMMAND_FIELDS, sizeof(plem_command)}, {"plem_outcome", OUTCOME_FIELDS, sizeof(plem_outcome)},
        {"plem_event", EVENT_FIELDS, sizeof(plem_event)}, {"plem_arm", ARM_FIELDS, sizeof(plem_arm)},
        {"plem_series", SERIES_FIELDS, sizeof(plem_series)}, {"plem_stats", STATS_FIELDS, sizeof(plem_stats)},
        {"plem_master_status", MASTER_STATUS_FIELDS, sizeof(plem_master_status)}};
    PyObject *result = Py_BuildValue("{s:i,s:i,s:i}", "max_joints", PLEM_MAX_JOINTS, "order", PLEM_ORDER,
                                     "stop_segments", PLEM_STOP_SEGMENTS);
    for (size_t i = 0; result && i < sizeof STRUCTURES / sizeof STRUCTURES[0]; i++) {
        PyObject *table = fields_dict(STRUCTURES[i].fields, STRUCTURES[i].size);
        if (!table || PyDict_SetItemString(result, STRUCTURES[i].name, table) < 0) Py_CLEAR(result);
        Py_XDECREF(table);
    }
    PyObject *constants = result ? constants_dict() : NULL;
    if (result && (!constants || PyDict_SetItemString(result, "constants", constants) < 0)) Py_CLEAR(result);
    Py_XDECREF(constants);
    return result;
}

static PyObject *build(PyObject *self, PyObject *unused) {
    (void)self, (void)unused;
#if defined(__SANITIZE_ADDRESS__)
    const int sanitized = 1;
#else
    const int sanitized = 0;
#endif
    return Py_BuildValue("{s:s,s:l,s:O,s:i,s:s}", "compiler", "gcc " __VERSION__, "standard", (long)__STDC_VERSION__,
                         "sanitized", sanitized ? Py_True : Py_False, "max_joints", PLEM_MAX_JOINTS, "ethercat",
                         "SOEM " PLEM_SOEM_VERSION);
}

static PyMethodDef METHODS[] = {
    {"build", build, METH_NOARGS, "How the core was built: compiler, C standard, sanitizers, EtherCAT master."},
    {"layout", layout, METH_NOARGS, "Offset and size of every field of every structure, and each one's size."},
    {"inverse_dynamics", inverse_dynamics, METH_VARARGS, "inverse_dynamics(model, q, v, a, tau_out)"},
    {"gravity", gravity, METH_VARARGS, "gravity(model, q, tau_out)"},
    {"forward_dynamics", forward_dynamics, METH_VARARGS, "forward_dynamics(model, q, v, tau, a_out)"},
    {"motion_sample", motion_sample, METH_VARARGS,
     "motion_sample(knots, coefficients, final, segments, dof, t, cursor_int32, out) -> True once over"},
    {"plan_stop", plan_stop, METH_VARARGS,
     "plan_stop(p, v, a, max_acceleration, max_jerk, knots_out, coefficients_out, final_out) -> segments"},
    {"follow", follow, METH_VARARGS,
     "follow(state, target_position, target_velocity, speed, max_velocity, max_acceleration, max_jerk, low, high, dt)"},
    {"arm_init", arm_init, METH_O, "arm_init(arm): a fresh arm (settings and model written) ready to cycle"},
    {"sim_read", sim_read, METH_O, "sim_read(sim) -> False while communication is lost"},
    {"sim_write", sim_write, METH_O, "sim_write(sim): controlwords, then one cycle"},
    {"sim_serve", sim_serve, METH_VARARGS, "sim_serve(sim, controlwords): a master's controlwords, then one cycle"},
    {"sim_quick_stop", sim_quick_stop, METH_O, "sim_quick_stop(sim) -> True when a drive changed state"},
    {"sim_fault", sim_fault, METH_VARARGS, "sim_fault(sim, drive, error_code, latched)"},
    {"sim_power_off", sim_power_off, METH_O, "sim_power_off(sim)"},
    {"power_init", power_init, METH_VARARGS, "power_init(power, dof)"},
    {"power_request", power_request, METH_VARARGS, "power_request(power, state)"},
    {"power_request_reset", power_request_reset, METH_O, "power_request_reset(power)"},
    {"power_master_lost", power_master_lost, METH_O, "power_master_lost(power)"},
    {"power_commands", power_commands, METH_VARARGS, "power_commands(power, seen_int32, out_uint16)"},
    {"decode_statusword", decode_statusword, METH_VARARGS, "decode_statusword(word) -> state"},
    {"statusword_of", statusword_of, METH_VARARGS, "statusword_of(state) -> word"},
    {"next_controlword", next_controlword, METH_VARARGS, "next_controlword(state, target, previous) -> word"},
    {"drive_transition", drive_transition, METH_VARARGS, "drive_transition(state, controlword, previous) -> state"},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_core", "plem's compiled core.", -1, METHODS,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__core(void) {
    if (PyType_Ready(&CORE_TYPE) < 0) return NULL;
    PyObject *module = PyModule_Create(&MODULE);
    if (module && (PyModule_AddObjectRef(module, "Core", (PyObject *)&CORE_TYPE) < 0 || plem_add_master(module) < 0))
        Py_CLEAR(module);
    return module;
}
