/* The EtherCAT master of one arm, on SOEM (third_party/soem, v1.4.0) compiled into the core.
 *
 * One SOEM context per interface, owned here: Python brings the segment up through it (master_binding.c) and the
 * real-time thread exchanges process data through it, receiving the answer to the frame it sent last cycle before
 * sending the next, so the frame's round trip overlaps the sleep. Nothing in the cycle allocates or takes the
 * interpreter lock; SOEM's own socket mutexes use priority inheritance.
 */
#ifndef PLEM_MASTER_H
#define PLEM_MASTER_H

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#include "ethercat.h"
#include "plem_core.h"

/* Bytes of process data the master maps: far more than 16 drives need. */
#define PLEM_IOMAP_BYTES 4096

/* plem's PDOs as they lie on the wire (little-endian, packed), one RxPDO and one TxPDO per drive. The same
 * assignment is written by SDO in PREOP (plem.fieldbus.ethercat.objects, checked against these at import). */
enum plem_rx_offsets {
    PLEM_RX_CONTROLWORD = 0, PLEM_RX_TARGET_POSITION = 2, PLEM_RX_VELOCITY_OFFSET = 6, PLEM_RX_TORQUE_OFFSET = 10,
    PLEM_RX_MODE = 12, PLEM_RX_BYTES = 13,
};
enum plem_tx_offsets {
    PLEM_TX_STATUSWORD = 0, PLEM_TX_POSITION = 2, PLEM_TX_VELOCITY = 6, PLEM_TX_TORQUE = 10, PLEM_TX_ERROR_CODE = 12,
    PLEM_TX_MODE_DISPLAY = 14, PLEM_TX_BYTES = 15,
    PLEM_TX_DIGITAL_INPUTS = 15, PLEM_TX_BYTES_WITH_INPUTS = 19,   /* drives that map 0x60FD after the rest */
};

/* What the cycle tells Python about the bus (read in place, each counter written by the cycle alone). */
typedef struct {
    int64_t exchanges;               /* process-data exchanges the cycle made */
    int64_t lost_frames;             /* answers that did not come back */
    int64_t working_counter_errors;  /* answers with a working counter short of the expected one */
    int64_t bad_cycles;              /* bad answers in a row now */
    int32_t working_counter;         /* of the last answer; -1 when none came back */
    int32_t expected_working_counter;
    int32_t communication_ok;        /* 0 after bad_cycles_to_fault bad answers in a row, until a good one */
    int32_t pad;
    plem_series exchange;            /* time the cycle spends in SOEM's receive and send (the wire's share) */
} plem_master_status;

/* The master: SOEM's context and everything it points into, the process image and the cycle's settings. */
typedef struct plem_master {
    ecx_contextt context;
    ecx_portt port;
    ec_slavet slaves[EC_MAXSLAVE];
    int slave_count;
    ec_groupt groups[EC_MAXGROUP];
    uint8 esibuf[EC_MAXEEPBUF];
    uint32 esimap[EC_MAXEEPBITMAP];
    ec_eringt errors;
    ec_idxstackT index_stack;
    boolean error_flag;
    int64 dc_time;
    ec_SMcommtypet sm_commtype[EC_MAX_MAPT];
    ec_PDOassignt pdo_assign[EC_MAX_MAPT];
    ec_PDOdesct pdo_description[EC_MAX_MAPT];
    ec_eepromSMt eeprom_sm;
    ec_eepromFMMUt eeprom_fmmu;
    uint8 iomap[PLEM_IOMAP_BYTES];
    int32_t open;                    /* the socket is open */
    int32_t dof;                     /* drives the cycle exchanges with (slaves 1..dof); 0 before the mapping */
    int32_t receive_timeout_us;      /* longest wait for last cycle's answer */
    int32_t bad_cycles_to_fault;
    int32_t outstanding;             /* a frame was sent whose answer has not been received */
    int32_t in_cycle;                /* a core thread, or the keepalive, exchanges through this master */
    double newton_metres_per_unit[PLEM_MAX_JOINTS];   /* torque objects (per mille of rated) to N·m at the joint */
    double units_per_newton_metre[PLEM_MAX_JOINTS];   /* the torque offset sent per N·m; 0: none sent */
    int64_t wire_ns;                 /* the current cycle's time in receive and send */
    uint32_t inputs_mapped;          /* bit j: drive j maps its digital inputs (0x60FD) */
    int32_t pad;
    plem_master_status status;
    /* the keepalive: frames every period from OP until a core cycles, on a thread that needs no interpreter */
    pthread_t keepalive;
    atomic_int keepalive_stop;
    int32_t keepalive_running;
    int32_t keepalive_timeout_us;
    int64_t keepalive_period_ns;
} plem_master;

/* A fresh master's context wired to its own storage (no socket yet). */
void plem_master_init(plem_master *master);
/* Send the outputs and wait for their answer (bring-up and shut-down, outside the cycle); the working counter. */
int plem_master_exchange(plem_master *master, int timeout_us);
/* The keepalive thread's body: an exchange every keepalive_period_ns until keepalive_stop. */
void *plem_master_keepalive(void *master);

#endif
