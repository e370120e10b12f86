/* plem.control._core.Master: the EtherCAT master of one interface, for Python's bring-up, scan, recovery and
 * shut-down, and for a Core whose real-time thread exchanges process data through it.
 *
 * Every call that waits on the wire releases the interpreter lock. Slaves are numbered from 1, as SOEM does.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <net/if.h>
#include <stddef.h>
#include <string.h>

#include "master.h"
#include "master_binding.h"

typedef struct {
    PyObject_HEAD
    plem_master *master;
} Master;

static PyObject *SDO_ERROR;

/* Stop the keepalive thread and wait for it, without the interpreter lock (it never needs it). */
static void stop_keepalive(plem_master *m) {
    if (!m || !m->keepalive_running) return;
    atomic_store_explicit(&m->keepalive_stop, 1, memory_order_release);
    Py_BEGIN_ALLOW_THREADS
    pthread_join(m->keepalive, NULL);
    Py_END_ALLOW_THREADS
    m->keepalive_running = 0;
    m->in_cycle = 0;
}

static void master_dealloc(Master *self) {
    stop_keepalive(self->master);
    if (self->master) {
        if (self->master->open) ecx_close(&self->master->context);
        PyMem_RawFree(self->master);
    }
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int master_init(Master *self, PyObject *args, PyObject *kwargs) {
    static char *keywords[] = {NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "", keywords)) return -1;
    if (self->master) return 0;
    self->master = PyMem_RawCalloc(1, sizeof(plem_master));
    if (!self->master) {
        PyErr_NoMemory();
        return -1;
    }
    plem_master_init(self->master);
    return 0;
}

plem_master *plem_master_of(PyObject *object) {
    if (!PyObject_TypeCheck(object, &PLEM_MASTER_TYPE)) {
        PyErr_SetString(PyExc_TypeError, "master: expected a plem.control._core.Master");
        return NULL;
    }
    return ((Master *)object)->master;
}

/* The master, open, and not exchanging from a core thread (which owns the cyclic frames while it runs). */
static plem_master *usable(Master *self) {
    plem_master *m = self->master;
    if (!m || !m->open) {
        PyErr_SetString(PyExc_RuntimeError, "the EtherCAT master is not open");
        return NULL;
    }
    if (m->in_cycle) {
        PyErr_SetString(PyExc_RuntimeError, "the core's cycle (or the keepalive before it) exchanges process data "
                                            "through this master");
        return NULL;
    }
    return m;
}

static int slave_index(plem_master *m, int slave, int allow_all) {
    if (slave < (allow_all ? 0 : 1) || slave > m->slave_count) {
        PyErr_Format(PyExc_IndexError, "slave %d: the segment has slaves 1..%d", slave, m->slave_count);
        return 0;
    }
    return 1;
}

static PyObject *master_open(Master *self, PyObject *args) {
    const char *interface;
    if (!PyArg_ParseTuple(args, "s", &interface)) return NULL;
    plem_master *m = self->master;
    if (!m) return PyErr_Format(PyExc_RuntimeError, "the EtherCAT master was not initialised");
    if (m->open) return PyErr_Format(PyExc_RuntimeError, "the EtherCAT master is already open");
    if (if_nametoindex(interface) == 0)   /* SOEM would open a socket bound to no interface */
        return PyErr_Format(PyExc_ConnectionError, "no interface named %s", interface);
    int opened;
    Py_BEGIN_ALLOW_THREADS
    opened = ecx_init(&m->context, interface);
    Py_END_ALLOW_THREADS
    if (opened <= 0) return PyErr_Format(PyExc_ConnectionError, "no raw socket could be opened on %s", interface);
    m->open = 1;
    Py_RETURN_NONE;
}

static PyObject *master_close(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = self->master;
    stop_keepalive(m);
    if (m && m->in_cycle) return PyErr_Format(PyExc_RuntimeError, "stop the core thread before closing its master");
    if (m && m->open) {
        Py_BEGIN_ALLOW_THREADS
        ecx_close(&m->context);
        Py_END_ALLOW_THREADS
        m->open = 0;
        m->dof = 0;
    }
    Py_RETURN_NONE;
}

static PyObject *master_config_init(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = usable(self);
    if (!m) return NULL;
    int found;
    m->dof = 0;
    Py_BEGIN_ALLOW_THREADS
    found = ecx_config_init(&m->context, FALSE);
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(found > 0 ? m->slave_count : 0);
}

static PyObject *master_slaves(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = self->master;
    PyObject *list = PyList_New(0);
    for (int i = 1; m && list && i <= m->slave_count; i++) {
        const ec_slavet *s = &m->slaves[i];
        PyObject *entry = Py_BuildValue(
            "{s:s,s:k,s:k,s:k,s:i,s:i,s:k,s:k,s:O,s:O,s:i}", "name", s->name, "vendor", (unsigned long)s->eep_man,
            "product", (unsigned long)s->eep_id, "revision", (unsigned long)s->eep_rev, "state", s->state,
            "al_status", s->ALstatuscode, "outputs", (unsigned long)s->Obytes, "inputs", (unsigned long)s->Ibytes,
            "coe", (s->mbx_proto & ECT_MBXPROT_COE) ? Py_True : Py_False, "has_dc", s->hasdc ? Py_True : Py_False,
            "address", s->configadr);
        if (!entry || PyList_Append(list, entry) < 0) Py_CLEAR(list);
        Py_XDECREF(entry);
    }
    return list;
}

static PyObject *master_read_state(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = usable(self);
    if (!m) return NULL;
    int lowest;
    Py_BEGIN_ALLOW_THREADS
    lowest = ecx_readstate(&m->context);
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(lowest);
}

static PyObject *master_write_state(Master *self, PyObject *args) {
    int state, slave = 0;
    if (!PyArg_ParseTuple(args, "i|i", &state, &slave)) return NULL;
    plem_master *m = self->master;
    if (!m || !m->open) return PyErr_Format(PyExc_RuntimeError, "the EtherCAT master is not open");
    if (!slave_index(m, slave, 1)) return NULL;
    int wkc;   /* allowed while the core cycles: one register write, e.g. asking for OP again after a watchdog */
    Py_BEGIN_ALLOW_THREADS
    m->slaves[slave].state = (uint16)state;
    wkc = ecx_writestate(&m->context, (uint16)slave);
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(wkc);
}

static PyObject *master_state_check(Master *self, PyObject *args) {
    int state, timeout, slave = 0;
    if (!PyArg_ParseTuple(args, "ii|i", &state, &timeout, &slave)) return NULL;
    plem_master *m = usable(self);
    if (!m || !slave_index(m, slave, 1)) return NULL;
    int reached;
    Py_BEGIN_ALLOW_THREADS
    reached = ecx_statecheck(&m->context, (uint16)slave, (uint16)state, timeout);
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(reached);
}

/* After a failed SDO transfer: SdoError(abort code, words), the abort code 0 when the slave sent none (then the
 * words say what went wrong instead: SOEM's text of a mailbox error, an answer of the wrong size, no answer). */
static PyObject *sdo_failed(plem_master *m, int wkc) {
    ec_errort error;
    uint32_t abort = 0;
    const char *words = wkc == 0 ? "no answer (timeout)" : "mailbox error";
    while (ecx_poperror(&m->context, &error)) {
        if (error.Etype == EC_ERR_TYPE_SDO_ERROR) {
            abort = (uint32_t)error.AbortCode;
            words = ec_sdoerror2string(abort);
        } else if (!abort && error.Etype == EC_ERR_TYPE_MBX_ERROR) {
            words = ec_mbxerror2string(error.ErrorCode);
        } else if (!abort && error.Etype == EC_ERR_TYPE_PACKET_ERROR) {
            words = error.ErrorCode == 3 ? "the answer is larger than the object's size (data container too small)"
                                         : "an unexpected answer came back (not the SDO response asked for)";
        }
    }
    PyObject *value = Py_BuildValue("(ks)", (unsigned long)abort, words);
    if (value) PyErr_SetObject(SDO_ERROR, value);
    Py_XDECREF(value);
    return NULL;
}

static PyObject *master_sdo_read(Master *self, PyObject *args) {
    int slave, index, subindex, size;
    if (!PyArg_ParseTuple(args, "iiii", &slave, &index, &subindex, &size)) return NULL;
    plem_master *m = usable(self);
    if (!m || !slave_index(m, slave, 0)) return NULL;
    uint8_t data[512];
    if (size < 1 || size > (int)sizeof data) return PyErr_Format(PyExc_ValueError, "size %d outside 1..512", size);
    int wkc, got = size;
    Py_BEGIN_ALLOW_THREADS
    wkc = ecx_SDOread(&m->context, (uint16)slave, (uint16)index, (uint8)subindex, FALSE, &got, data, EC_TIMEOUTRXM);
    Py_END_ALLOW_THREADS
    if (wkc <= 0 || ecx_iserror(&m->context)) return sdo_failed(m, wkc);
    return PyBytes_FromStringAndSize((const char *)data, got);
}

static PyObject *master_sdo_write(Master *self, PyObject *args) {
    int slave, index, subindex;
    Py_buffer data;
    if (!PyArg_ParseTuple(args, "iiiy*", &slave, &index, &subindex, &data)) return NULL;
    plem_master *m = usable(self);
    PyObject *result = NULL;
    if (m && slave_index(m, slave, 0)) {
        int wkc;
        Py_BEGIN_ALLOW_THREADS
        wkc = ecx_SDOwrite(&m->context, (uint16)slave, (uint16)index, (uint8)subindex, FALSE, (int)data.len, data.buf,
                           EC_TIMEOUTRXM);
        Py_END_ALLOW_THREADS
        result = wkc <= 0 || ecx_iserror(&m->context) ? sdo_failed(m, wkc) : Py_NewRef(Py_None);
    }
    PyBuffer_Release(&data);
    return result;
}

static PyObject *master_config_map(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = usable(self);
    if (!m) return NULL;
    if (m->slave_count > PLEM_MAX_JOINTS)
        return PyErr_Format(PyExc_ValueError, "%d slaves: the core drives at most %d", m->slave_count,
                            PLEM_MAX_JOINTS);
    int size;
    Py_BEGIN_ALLOW_THREADS
    size = ecx_config_map_group(&m->context, m->iomap, 0);
    Py_END_ALLOW_THREADS
    const ec_groupt *g = &m->groups[0];
    if (size > PLEM_IOMAP_BYTES || (int64_t)g->Obytes + g->Ibytes > PLEM_IOMAP_BYTES)
        return PyErr_Format(PyExc_ValueError, "%d bytes of process data: the master maps at most %d", size,
                            PLEM_IOMAP_BYTES);
    m->status.expected_working_counter = g->outputsWKC * 2 + g->inputsWKC;
    return PyLong_FromLong(size);
}

static PyObject *master_config_dc(Master *self, PyObject *unused) {
    (void)unused;
    plem_master *m = usable(self);
    if (!m) return NULL;
    boolean found;
    Py_BEGIN_ALLOW_THREADS
    found = ecx_configdc(&m->context);
    Py_END_ALLOW_THREADS
    return PyBool_FromLong(found);
}

static PyObject *master_dc_sync0(Master *self, PyObject *args) {
    int slave, active;
    unsigned long cycle;
    long shift = 0;
    if (!PyArg_ParseTuple(args, "ipk|l", &slave, &active, &cycle, &shift)) return NULL;
    plem_master *m = usable(self);
    if (!m || !slave_index(m, slave, 0)) return NULL;
    Py_BEGIN_ALLOW_THREADS
    ecx_dcsync0(&m->context, (uint16)slave, (boolean)active, (uint32)cycle, (int32)shift);
    Py_END_ALLOW_THREADS
    Py_RETURN_NONE;
}

static PyObject *master_read_register(Master *self, PyObject *args) {
    int slave, address, size, timeout;
    if (!PyArg_ParseTuple(args, "iiii", &slave, &address, &size, &timeout)) return NULL;
    plem_master *m = self->master;   /* allowed while the core cycles: a diagnosis after a bad working counter */
    if (!m || !m->open) return PyErr_Format(PyExc_RuntimeError, "the EtherCAT master is not open");
    if (!slave_index(m, slave, 0)) return NULL;
    uint8_t data[64];
    if (size < 1 || size > (int)sizeof data) return PyErr_Format(PyExc_ValueError, "size %d outside 1..64", size);
    int wkc;
    Py_BEGIN_ALLOW_THREADS
    wkc = ecx_FPRD(&m->port, m->slaves[slave].configadr, (uint16)address, (uint16)size, data, timeout);
    Py_END_ALLOW_THREADS
    if (wkc <= 0) Py_RETURN_NONE;
    return PyBytes_FromStringAndSize((const char *)data, size);
}

static PyObject *master_exchange(Master *self, PyObject *args) {
    int timeout;
    if (!PyArg_ParseTuple(args, "i", &timeout)) return NULL;
    plem_master *m = usable(self);
    if (!m) return NULL;
    int wkc;
    Py_BEGIN_ALLOW_THREADS
    wkc = plem_master_exchange(m, timeout);
    Py_END_ALLOW_THREADS
    return PyLong_FromLong(wkc);
}

/* The process image of one slave: its inputs (`outputs` 0) or outputs (1). */
static uint8_t *image(plem_master *m, int slave, int outputs, Py_ssize_t *size) {
    if (!slave_index(m, slave, 0)) return NULL;
    const ec_slavet *s = &m->slaves[slave];
    *size = outputs ? s->Obytes : s->Ibytes;
    uint8_t *data = outputs ? s->outputs : s->inputs;
    if (!data) PyErr_Format(PyExc_RuntimeError, "slave %d has no process data mapped", slave);
    return data;
}

static PyObject *master_inputs(Master *self, PyObject *args) {
    int slave;
    Py_ssize_t size;
    if (!PyArg_ParseTuple(args, "i", &slave)) return NULL;
    plem_master *m = usable(self);
    uint8_t *data = m ? image(m, slave, 0, &size) : NULL;
    return data ? PyBytes_FromStringAndSize((const char *)data, size) : NULL;
}

static PyObject *master_set_outputs(Master *self, PyObject *args) {
    int slave;
    Py_buffer data;
    Py_ssize_t size;
    if (!PyArg_ParseTuple(args, "iy*", &slave, &data)) return NULL;
    plem_master *m = usable(self);
    uint8_t *out = m ? image(m, slave, 1, &size) : NULL;
    if (out && data.len != size) PyErr_Format(PyExc_ValueError, "slave %d maps %zd output bytes, got %zd", slave,
                                              size, data.len), out = NULL;
    if (out) memcpy(out, data.buf, (size_t)size);
    PyBuffer_Release(&data);
    if (!out) return NULL;
    Py_RETURN_NONE;
}

static PyObject *master_start_keepalive(Master *self, PyObject *args) {
    long long period;
    int timeout;
    if (!PyArg_ParseTuple(args, "Li", &period, &timeout)) return NULL;
    plem_master *m = usable(self);
    if (!m) return NULL;
    if (period <= 0 || timeout < 0)
        return PyErr_Format(PyExc_ValueError, "keepalive: period %lld ns > 0, timeout %d µs >= 0", period, timeout);
    m->keepalive_period_ns = period;
    m->keepalive_timeout_us = timeout;
    atomic_store_explicit(&m->keepalive_stop, 0, memory_order_relaxed);
    m->in_cycle = 1;
    int error = pthread_create(&m->keepalive, NULL, plem_master_keepalive, m);
    if (error) {
        m->in_cycle = 0;
        return PyErr_Format(PyExc_OSError, "the keepalive thread could not be created: %s", strerror(error));
    }
    m->keepalive_running = 1;
    Py_RETURN_NONE;
}

static PyObject *master_stop_keepalive(Master *self, PyObject *unused) {
    (void)unused;
    stop_keepalive(self->master);
    Py_RETURN_NONE;
}

static PyObject *master_prepare(Master *self, PyObject *args, PyObject *kwargs) {
    static char *keywords[] = {"torque_units", "bad_cycles_to_fault", "receive_timeout_us", "torque_commands", NULL};
    PyObject *units, *commands = NULL;
    int bad, timeout;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "Oii|O", keywords, &units, &bad, &timeout, &commands)) return NULL;
    plem_master *m = usable(self);
    if (!m) return NULL;
    PyObject *sequence = PySequence_Fast(units, "torque_units: a sequence of N·m per torque unit, one per drive");
    if (!sequence) return NULL;
    PyObject *sent = commands ? PySequence_Fast(commands, "torque_commands: a sequence of booleans, one per drive")
                              : NULL;
    if (commands && !sent) {
        Py_DECREF(sequence);
        return NULL;
    }
    Py_ssize_t n = PySequence_Fast_GET_SIZE(sequence);
    int ok = n >= 1 && n == m->slave_count && bad >= 1 && timeout >= 0 && m->status.expected_working_counter > 0
             && (!sent || PySequence_Fast_GET_SIZE(sent) == n);
    m->inputs_mapped = 0;
    for (Py_ssize_t i = 0; ok && i < n; i++) {
        const ec_slavet *s = &m->slaves[i + 1];
        ok = s->Obytes == PLEM_RX_BYTES && (s->Ibytes == PLEM_TX_BYTES || s->Ibytes == PLEM_TX_BYTES_WITH_INPUTS)
             && s->outputs && s->inputs;
        if (ok && s->Ibytes == PLEM_TX_BYTES_WITH_INPUTS) m->inputs_mapped |= 1u << i;
        double per_unit = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(sequence, i));
        int send = sent ? PyObject_IsTrue(PySequence_Fast_GET_ITEM(sent, i)) : 1;
        m->newton_metres_per_unit[i] = per_unit;
        m->units_per_newton_metre[i] = send > 0 && per_unit != 0.0 ? 1.0 / per_unit : 0.0;
    }
    Py_DECREF(sequence);
    Py_XDECREF(sent);
    if (PyErr_Occurred()) return NULL;
    if (!ok)
        return PyErr_Format(PyExc_ValueError, "prepare: %zd drives, %d slaves, each mapping %d output and %d or %d "
                            "input bytes, bad cycles %d >= 1, timeout %d >= 0", n, m->slave_count, PLEM_RX_BYTES,
                            PLEM_TX_BYTES, PLEM_TX_BYTES_WITH_INPUTS, bad, timeout);
    m->dof = (int32_t)n;
    m->bad_cycles_to_fault = bad;
    m->receive_timeout_us = timeout;
    Py_RETURN_NONE;
}

/* The master's status as a read-only buffer that keeps the master alive while a view of it exists. */
static int master_getbuffer(Master *self, Py_buffer *view, int flags) {
    if (!self->master) {
        PyErr_SetString(PyExc_BufferError, "the EtherCAT master was not initialised");
        return -1;
    }
    return PyBuffer_FillInfo(view, (PyObject *)self, &self->master->status, sizeof(plem_master_status), 1, flags);
}

static PyBufferProcs MASTER_BUFFER = {.bf_getbuffer = (getbufferproc)master_getbuffer};

static PyObject *master_status(Master *self, void *closure) {
    (void)closure;
    return PyMemoryView_FromObject((PyObject *)self);
}

static PyObject *master_is_open(Master *self, void *closure) {
    (void)closure;
    return PyBool_FromLong(self->master && self->master->open);
}

static PyObject *al_status_text(PyObject *self, PyObject *args) {
    (void)self;
    unsigned int code;
    if (!PyArg_ParseTuple(args, "I", &code)) return NULL;
    return PyUnicode_FromString(ec_ALstatuscode2string((uint16)code));
}

static PyGetSetDef MASTER_GETSET[] = {
    {"status", (getter)master_status, NULL, "The cycle's bus figures (plem_master_status), read in place.", NULL},
    {"is_open", (getter)master_is_open, NULL, "The interface's raw socket is open.", NULL},
    {NULL, NULL, NULL, NULL, NULL}};

static PyMethodDef MASTER_METHODS[] = {
    {"open", (PyCFunction)master_open, METH_VARARGS, "open(interface): a raw socket on the interface."},
    {"close", (PyCFunction)master_close, METH_NOARGS, "Release the interface; safe to repeat."},
    {"config_init", (PyCFunction)master_config_init, METH_NOARGS, "Enumerate the slaves (to PREOP); how many."},
    {"slaves", (PyCFunction)master_slaves, METH_NOARGS, "What enumeration and the last read_state found, per slave."},
    {"read_state", (PyCFunction)master_read_state, METH_NOARGS, "Read every slave's AL state; the lowest."},
    {"write_state", (PyCFunction)master_write_state, METH_VARARGS,
     "write_state(state, slave=0): request an AL state of one slave, or of all (0)."},
    {"state_check", (PyCFunction)master_state_check, METH_VARARGS,
     "state_check(state, timeout_us, slave=0): wait for the state; the state reached."},
    {"sdo_read", (PyCFunction)master_sdo_read, METH_VARARGS, "sdo_read(slave, index, subindex, size): the bytes."},
    {"sdo_write", (PyCFunction)master_sdo_write, METH_VARARGS, "sdo_write(slave, index, subindex, data)."},
    {"config_map", (PyCFunction)master_config_map, METH_NOARGS, "Map the process data; its size in bytes."},
    {"config_dc", (PyCFunction)master_config_dc, METH_NOARGS, "Set up distributed clocks; whether any slave has one."},
    {"dc_sync0", (PyCFunction)master_dc_sync0, METH_VARARGS, "dc_sync0(slave, active, cycle_ns, shift_ns=0)."},
    {"read_register", (PyCFunction)master_read_register, METH_VARARGS,
     "read_register(slave, address, size, timeout_us): the bytes, None when the slave does not answer."},
    {"exchange", (PyCFunction)master_exchange, METH_VARARGS,
     "exchange(timeout_us): send the outputs, wait for the answer; the working counter."},
    {"inputs", (PyCFunction)master_inputs, METH_VARARGS, "inputs(slave): the slave's input bytes."},
    {"set_outputs", (PyCFunction)master_set_outputs, METH_VARARGS, "set_outputs(slave, data)."},
    {"start_keepalive", (PyCFunction)master_start_keepalive, METH_VARARGS,
     "start_keepalive(period_ns, timeout_us): exchange every period on a thread of the master's own, until "
     "stop_keepalive(), so no watchdog expires before a core cycles."},
    {"stop_keepalive", (PyCFunction)master_stop_keepalive, METH_NOARGS,
     "Stop the keepalive; returns once its last exchange has ended. Safe to repeat."},
    {"prepare", (PyCFunction)(void (*)(void))master_prepare, METH_VARARGS | METH_KEYWORDS,
     "prepare(torque_units, bad_cycles_to_fault, receive_timeout_us, torque_commands=None): ready for a core's "
     "cycle; torque_commands[i] false sends drive i no torque offset."},
    {NULL, NULL, 0, NULL}};

PyTypeObject PLEM_MASTER_TYPE = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "plem.control._core.Master",
    .tp_basicsize = sizeof(Master),
    .tp_dealloc = (destructor)master_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Master(): the EtherCAT master of one interface, on SOEM v1.4.0.",
    .tp_methods = MASTER_METHODS,
    .tp_getset = MASTER_GETSET,
    .tp_as_buffer = &MASTER_BUFFER,
    .tp_init = (initproc)master_init,
    .tp_new = PyType_GenericNew,
};

static PyMethodDef FUNCTIONS[] = {
    {"al_status_text", al_status_text, METH_VARARGS, "al_status_text(code): SOEM's words for an AL status code."},
    {NULL, NULL, 0, NULL}};

int plem_add_master(PyObject *module) {
    SDO_ERROR = PyErr_NewExceptionWithDoc("plem.control._core.SdoError",
                                          "An SDO transfer failed: args (abort code, words); the code 0 without one.",
                                          PyExc_RuntimeError, NULL);
    if (!SDO_ERROR || PyModule_AddObjectRef(module, "SdoError", SDO_ERROR) < 0) return -1;
    if (PyType_Ready(&PLEM_MASTER_TYPE) < 0 || PyModule_AddObjectRef(module, "Master", (PyObject *)&PLEM_MASTER_TYPE) < 0)
        return -1;
    if (PyModule_AddFunctions(module, FUNCTIONS) < 0) return -1;
    return PyModule_AddIntConstant(module, "IOMAP_BYTES", PLEM_IOMAP_BYTES);
}
