/* plem.control._core: the compiled core's functions over structures held in Python-owned buffers.
 *
 * Each structure arrives as a writable, contiguous, 8-byte aligned buffer at least the structure's size (a
 * numpy array of the dtype plem.control.compiled builds from `layout()`); vectors arrive as float64, int32 or
 * uint16 buffers of at least the arm's joint count. Calls are a few microseconds and keep the interpreter lock.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stddef.h>

#include "plem_core.h"

/* Nested structures travel as buffers of their own, which the core takes only 8-byte aligned. */
_Static_assert(offsetof(plem_sim, power) % 8 == 0, "plem_sim.power must be 8-byte aligned");
_Static_assert(offsetof(plem_sim, model) % 8 == 0, "plem_sim.model must be 8-byte aligned");

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

static PyObject *sim_read(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    PyObject *result = sim ? PyBool_FromLong(plem_sim_read(sim)) : NULL;
    release(&arg, 1);
    return result;
}

static PyObject *sim_write(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    if (sim) plem_sim_write(sim);
    release(&arg, 1);
    return sim ? Py_NewRef(Py_None) : NULL;
}

static PyObject *sim_quick_stop(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    PyObject *result = sim ? PyBool_FromLong(plem_sim_quick_stop(sim)) : NULL;
    release(&arg, 1);
    return result;
}

static PyObject *sim_power_off(PyObject *self, PyObject *object) {
    (void)self;
    argument arg = {{0}, 0};
    plem_sim *sim = take_sim(object, &arg);
    if (sim) plem_sim_power_off(sim);
    release(&arg, 1);
    return sim ? Py_NewRef(Py_None) : NULL;
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
    FIELD(plem_sim, external), FIELD(plem_sim, stop_q), FIELD(plem_sim, stop_v), FIELD(plem_sim, spike),
    FIELD(plem_sim, stuck), FIELD(plem_sim, latched), FIELD(plem_sim, stopping), FIELD(plem_sim, state),
    FIELD(plem_sim, statusword), FIELD(plem_sim, error_code), FIELD(plem_sim, controlword), FIELD(plem_sim, lost),
    FIELD(plem_sim, lost_reads), FIELD(plem_sim, lost_frames), FIELD(plem_sim, io_target_position),
    FIELD(plem_sim, io_velocity_offset), FIELD(plem_sim, io_torque_offset), FIELD(plem_sim, io_mode),
    FIELD(plem_sim, io_position), FIELD(plem_sim, io_velocity), FIELD(plem_sim, io_torque),
    FIELD(plem_sim, io_statusword), FIELD(plem_sim, io_error_code), FIELD(plem_sim, power),
    FIELD(plem_sim, scratch), FIELD(plem_sim, model), {NULL, 0, 0}};

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
    PyObject *model = fields_dict(MODEL_FIELDS, sizeof(plem_model));
    PyObject *power = fields_dict(POWER_FIELDS, sizeof(plem_power));
    PyObject *sim = fields_dict(SIM_FIELDS, sizeof(plem_sim));
    PyObject *result = (model && power && sim)
        ? Py_BuildValue("{s:O,s:O,s:O,s:i,s:i,s:i}", "plem_model", model, "plem_power", power, "plem_sim", sim,
                        "max_joints", PLEM_MAX_JOINTS, "order", PLEM_ORDER, "stop_segments", PLEM_STOP_SEGMENTS)
        : NULL;
    Py_XDECREF(model);
    Py_XDECREF(power);
    Py_XDECREF(sim);
    return result;
}

static PyMethodDef METHODS[] = {
    {"layout", layout, METH_NOARGS, "Offset and size of every field of every structure, and each one's size."},
    {"inverse_dynamics", inverse_dynamics, METH_VARARGS, "inverse_dynamics(model, q, v, a, tau_out)"},
    {"gravity", gravity, METH_VARARGS, "gravity(model, q, tau_out)"},
    {"forward_dynamics", forward_dynamics, METH_VARARGS, "forward_dynamics(model, q, v, tau, a_out)"},
    {"motion_sample", motion_sample, METH_VARARGS,
     "motion_sample(knots, coefficients, final, segments, dof, t, cursor_int32, out) -> True once over"},
    {"plan_stop", plan_stop, METH_VARARGS,
     "plan_stop(p, v, a, max_acceleration, max_jerk, knots_out, coefficients_out, final_out) -> segments"},
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

PyMODINIT_FUNC PyInit__core(void) { return PyModule_Create(&MODULE); }
