/* The baseline of benchmarks/ethercat.py: a bare SOEM loop in C, shaped like SOEM's red_test.
 *
 * Usage: bare_soem INTERFACE SECONDS RX_MAPPING... -- TX_MAPPING...
 * (the mapping words of plem's RxPDO 0x1600 and TxPDO 0x1A00, as plem.fieldbus.ethercat.objects gives them).
 * Brings the segment to OP with that PDO assignment and distributed clocks, then runs at SCHED_FIFO 98 and
 * 1 kHz: sleep to an absolute deadline, receive the answer to last cycle's frame, enable the drives holding
 * where they are, send. Prints one JSON line: wake-up latency and the time in receive and send (µs), bad cycles.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

#include "ethercat.h"

#define PERIOD_NS 1000000LL
#define RECEIVE_TIMEOUT_US 500
#define MAX_ENTRIES 16

static char iomap[4096];

static int64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000LL + t.tv_nsec;
}

static void sleep_until(int64_t deadline) {
    struct timespec at = {.tv_sec = deadline / 1000000000LL, .tv_nsec = deadline % 1000000000LL};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, NULL) == EINTR) {
    }
}

static int compare(const void *a, const void *b) {
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static double percentile(int64_t *values, int count, double q) {
    qsort(values, (size_t)count, sizeof *values, compare);
    int index = (int)(q / 100.0 * (count - 1) + 0.5);
    return (double)values[index] / 1e3;
}

static void assign(uint16 slave, uint16 assign_index, uint16 pdo, const uint32 *entries, int count) {
    uint8 zero = 0, one = 1, n = (uint8)count;
    ec_SDOwrite(slave, assign_index, 0, FALSE, 1, &zero, EC_TIMEOUTRXM);
    ec_SDOwrite(slave, pdo, 0, FALSE, 1, &zero, EC_TIMEOUTRXM);
    for (int i = 0; i < count; i++) {
        uint32 entry = entries[i];
        ec_SDOwrite(slave, pdo, (uint8)(i + 1), FALSE, 4, &entry, EC_TIMEOUTRXM);
    }
    ec_SDOwrite(slave, pdo, 0, FALSE, 1, &n, EC_TIMEOUTRXM);
    ec_SDOwrite(slave, assign_index, 1, FALSE, 2, &pdo, EC_TIMEOUTRXM);
    ec_SDOwrite(slave, assign_index, 0, FALSE, 1, &one, EC_TIMEOUTRXM);
}

/* The next controlword toward operation enabled, from a CiA402 statusword. */
static uint16 enabling(uint16 sw) {
    if (sw & 0x0008) return 0x0080;                 /* fault: reset */
    if ((sw & 0x4F) == 0x40) return 0x0006;         /* switch on disabled: shutdown */
    if ((sw & 0x6F) == 0x21) return 0x0007;         /* ready to switch on: switch on */
    return 0x000F;                                  /* switched on or enabled: enable operation */
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: bare_soem INTERFACE SECONDS RX_MAPPING... -- TX_MAPPING...\n");
        return 2;
    }
    int count = (int)(atof(argv[2]) * 1000), rx_count = 0, tx_count = 0, in_tx = 0;
    uint32 rx[MAX_ENTRIES], tx[MAX_ENTRIES];
    for (int i = 3; i < argc; i++) {
        if (strcmp(argv[i], "--") == 0) in_tx = 1;
        else if (in_tx && tx_count < MAX_ENTRIES) tx[tx_count++] = (uint32)strtoul(argv[i], NULL, 0);
        else if (!in_tx && rx_count < MAX_ENTRIES) rx[rx_count++] = (uint32)strtoul(argv[i], NULL, 0);
    }
    if (ec_init(argv[1]) <= 0 || ec_config_init(FALSE) <= 0) {
        fprintf(stderr, "no slaves on %s\n", argv[1]);
        return 1;
    }
    ec_statecheck(0, EC_STATE_PRE_OP, EC_TIMEOUTSTATE);
    for (uint16 s = 1; s <= ec_slavecount; s++) {
        assign(s, 0x1C12, 0x1600, rx, rx_count);
        assign(s, 0x1C13, 0x1A00, tx, tx_count);
        int8 csp = 8;
        ec_SDOwrite(s, 0x6060, 0, FALSE, 1, &csp, EC_TIMEOUTRXM);
    }
    ec_config_map(iomap);
    if (ec_configdc())
        for (uint16 s = 1; s <= ec_slavecount; s++)
            if (ec_slave[s].hasdc) ec_dcsync0(s, TRUE, (uint32)PERIOD_NS, 0);
    ec_statecheck(0, EC_STATE_SAFE_OP, EC_TIMEOUTSTATE);
    int expected = ec_group[0].outputsWKC * 2 + ec_group[0].inputsWKC;
    ec_slave[0].state = EC_STATE_OPERATIONAL;
    ec_send_processdata();
    ec_receive_processdata(EC_TIMEOUTRET);
    ec_writestate(0);
    for (int tries = 0; tries < 500 && ec_slave[0].state != EC_STATE_OPERATIONAL; tries++) {
        ec_send_processdata();
        ec_receive_processdata(EC_TIMEOUTRET);
        ec_statecheck(0, EC_STATE_OPERATIONAL, 10000);
    }
    if (ec_slave[0].state != EC_STATE_OPERATIONAL) {
        fprintf(stderr, "the slaves did not reach OP\n");
        return 1;
    }
    int32 hold[EC_MAXSLAVE];
    for (uint16 s = 1; s <= ec_slavecount; s++) memcpy(&hold[s], ec_slave[s].inputs + 2, 4);

    int64_t *latency = calloc((size_t)count, sizeof(int64_t)), *exchange = calloc((size_t)count, sizeof(int64_t));
    struct sched_param fifo = {.sched_priority = 98};
    if (sched_setscheduler(0, SCHED_FIFO, &fifo) != 0) perror("SCHED_FIFO");
    mlockall(MCL_CURRENT | MCL_FUTURE);
    int bad = 0, sent = 0;
    int64_t deadline = now_ns() + PERIOD_NS;
    for (int i = 0; i < count; i++) {
        sleep_until(deadline);
        int64_t woke = now_ns();
        int wkc = sent ? ec_receive_processdata(RECEIVE_TIMEOUT_US) : expected;
        int64_t received = now_ns();
        bad += wkc != expected;
        for (uint16 s = 1; s <= ec_slavecount; s++) {
            uint16 sw, cw;
            memcpy(&sw, ec_slave[s].inputs, 2);
            cw = enabling(sw);
            memcpy(ec_slave[s].outputs, &cw, 2);
            memcpy(ec_slave[s].outputs + 2, &hold[s], 4);
            ec_slave[s].outputs[12] = 8;
        }
        int64_t sending = now_ns();
        ec_send_processdata();
        sent = 1;
        exchange[i] = (received - woke) + (now_ns() - sending);
        latency[i] = woke - deadline;
        deadline += PERIOD_NS;
        int64_t done = now_ns();
        if (done > deadline) deadline += ((done - deadline) / PERIOD_NS + 1) * PERIOD_NS;
    }
    ec_receive_processdata(EC_TIMEOUTRET);
    printf("{\"cycles\": %d, \"bad\": %d, \"exchange_p50\": %.2f, \"exchange_p99\": %.2f, \"exchange_max\": %.2f, "
           "\"latency_p99\": %.2f}\n", count, bad, percentile(exchange, count, 50), percentile(exchange, count, 99),
           percentile(exchange, count, 100), percentile(latency, count, 99));
    ec_slave[0].state = EC_STATE_INIT;
    ec_writestate(0);
    ec_close();
    return 0;
}
