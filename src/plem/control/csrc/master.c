/* The EtherCAT master's share of the cycle: last cycle's answer into the arm, this cycle's outputs onto the wire,
 * working-counter checks. Bring-up, recovery and shut-down are Python's, through master_binding.c. */
#include <math.h>
#include <stdatomic.h>
#include <string.h>

#include "clock.h"
#include "master.h"

void plem_master_init(plem_master *m) {
    m->context = (ecx_contextt){
        .port = &m->port, .slavelist = m->slaves, .slavecount = &m->slave_count, .maxslave = EC_MAXSLAVE,
        .grouplist = m->groups, .maxgroup = EC_MAXGROUP, .esibuf = m->esibuf, .esimap = m->esimap,
        .elist = &m->errors, .idxstack = &m->index_stack, .ecaterror = &m->error_flag, .DCtime = &m->dc_time,
        .SMcommtype = m->sm_commtype, .PDOassign = m->pdo_assign, .PDOdesc = m->pdo_description,
        .eepSM = &m->eeprom_sm, .eepFMMU = &m->eeprom_fmmu,
    };
    m->status.working_counter = -1;
    m->status.communication_ok = 1;
}

/* Little-endian fields of the process image, whatever the host's byte order. */
static uint16_t get16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static uint32_t get32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16
                                                 | (uint32_t)p[3] << 24; }
static void put16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v, p[1] = (uint8_t)(v >> 8); }
static void put32(uint8_t *p, uint32_t v) {
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> 8 * i);
}

static int32_t saturate32(int64_t v) { return v > INT32_MAX ? INT32_MAX : v < INT32_MIN ? INT32_MIN : (int32_t)v; }

static void decode(plem_master *m, plem_arm *arm) {
    arm->io_inputs_reported = m->inputs_mapped;
    for (int i = 0; i < m->dof; i++) {
        const uint8_t *in = m->slaves[i + 1].inputs;
        /* 32-bit encoder counts unwrapped against the last reading: a continuous joint may turn forever */
        int32_t raw = (int32_t)get32(in + PLEM_TX_POSITION);
        int64_t last = arm->io_position[i];
        arm->io_position[i] = last + (int32_t)((uint32_t)raw - (uint32_t)last);
        arm->io_statusword[i] = get16(in + PLEM_TX_STATUSWORD);
        arm->io_velocity[i] = (int32_t)get32(in + PLEM_TX_VELOCITY);
        arm->io_torque[i] = (int16_t)get16(in + PLEM_TX_TORQUE) * m->newton_metres_per_unit[i];
        arm->io_error_code[i] = get16(in + PLEM_TX_ERROR_CODE);
        arm->io_digital_inputs[i] = m->inputs_mapped >> i & 1u ? get32(in + PLEM_TX_DIGITAL_INPUTS) : 0;
    }
}

static void count(int64_t *counter) {
    atomic_store_explicit((_Atomic int64_t *)counter, *counter + 1, memory_order_relaxed);
}

int plem_master_read(plem_master *m, plem_arm *arm) {
    plem_master_status *s = &m->status;
    m->wire_ns = 0;
    if (!m->outstanding) {   /* the first cycle: the inputs are the answer to the last exchange outside the cycle */
        decode(m, arm);
        return s->communication_ok;
    }
    int64_t start = plem_now_ns();
    int wkc = ecx_receive_processdata(&m->context, m->receive_timeout_us);
    m->wire_ns = plem_now_ns() - start;
    m->outstanding = 0;
    s->working_counter = wkc;
    if (wkc == s->expected_working_counter) {
        decode(m, arm);
        s->bad_cycles = 0;
        s->communication_ok = 1;
        return 1;
    }
    count(wkc <= 0 ? &s->lost_frames : &s->working_counter_errors);
    s->bad_cycles++;
    if (s->bad_cycles < m->bad_cycles_to_fault) return s->communication_ok;
    s->communication_ok = 0;
    return 0;
}

int plem_master_fresh(const plem_master *m) { return m->status.bad_cycles == 0; }

void plem_master_write(plem_master *m, const plem_arm *arm, const uint16_t *controlwords) {
    for (int i = 0; i < m->dof; i++) {
        uint8_t *out = m->slaves[i + 1].outputs;
        double units = arm->io_torque_offset[i] * m->units_per_newton_metre[i];
        units = units > 32767.0 ? 32767.0 : units < -32768.0 ? -32768.0 : rint(units);
        put16(out + PLEM_RX_CONTROLWORD, controlwords[i]);
        put32(out + PLEM_RX_TARGET_POSITION, (uint32_t)arm->io_target_position[i]);   /* the drive's own 32 bits */
        put32(out + PLEM_RX_VELOCITY_OFFSET, (uint32_t)saturate32(arm->io_velocity_offset[i]));
        put16(out + PLEM_RX_TORQUE_OFFSET, (uint16_t)(int16_t)units);
        out[PLEM_RX_MODE] = (uint8_t)arm->io_mode[i];
    }
    int64_t start = plem_now_ns();
    ecx_send_processdata(&m->context);
    m->wire_ns += plem_now_ns() - start;
    m->outstanding = 1;
    count(&m->status.exchanges);
    plem_series_add(&m->status.exchange, m->wire_ns);
}

void *plem_master_keepalive(void *argument) {
    plem_master *m = argument;
    int64_t deadline = plem_now_ns();
    while (!atomic_load_explicit(&m->keepalive_stop, memory_order_acquire)) {
        deadline += m->keepalive_period_ns;
        plem_sleep_until(deadline);
        plem_master_exchange(m, m->keepalive_timeout_us);
        int64_t late = plem_now_ns() - deadline;
        if (late > m->keepalive_period_ns) deadline += late / m->keepalive_period_ns * m->keepalive_period_ns;
    }
    return NULL;
}

int plem_master_exchange(plem_master *m, int timeout_us) {
    if (m->outstanding) ecx_receive_processdata(&m->context, timeout_us);   /* the cycle's last frame */
    m->outstanding = 0;
    ecx_send_processdata(&m->context);
    return ecx_receive_processdata(&m->context, timeout_us);
}
