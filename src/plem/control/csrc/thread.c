/* The real-time thread: absolute deadlines, one cycle per period, timing statistics (compute without the time on
 * the EtherCAT wire), the rt_raw record and the overrun fault. It never touches the Python interpreter; Python reads what it writes from memory. */
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <string.h>

#include "clock.h"
#include "master.h"
#include "plem_core.h"
#include "thread.h"

#define RING_HOT_OFFSET 32
#define RING_SLOTS_OFFSET 64
#define RING_SLOT_HEADER 16
#define RAW_SCALARS 7

void plem_series_add(plem_series *s, int64_t value) {
    if (value < 0) value = 0;
    int64_t bin = value / 1000;
    s->histogram[bin < PLEM_HISTOGRAM_BINS ? bin : PLEM_HISTOGRAM_BINS - 1]++;
    s->window[s->count % PLEM_WINDOW] = value;
    if (s->count == 0 || value < s->min_ns) s->min_ns = value;
    if (value > s->max_ns) s->max_ns = value;
    s->total_ns += value;
    atomic_store_explicit((_Atomic int64_t *)&s->count, s->count + 1, memory_order_release);
}

void plem_raw_write(plem_raw_ring *ring, const plem_state_block *block, int dof, int64_t latency, int64_t compute,
                    double speed_override) {
    _Atomic int64_t *head = (_Atomic int64_t *)(ring->base + RING_HOT_OFFSET);
    int64_t n = atomic_load_explicit(head, memory_order_relaxed), i = n % ring->slots;
    uint8_t *slot = ring->base + RING_SLOTS_OFFSET + i * (RING_SLOT_HEADER + ring->slot_bytes);
    _Atomic uint64_t *sequence = (_Atomic uint64_t *)slot;
    atomic_store_explicit(sequence, (uint64_t)(2 * n + 1), memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    double *record = (double *)(slot + RING_SLOT_HEADER);
    for (int k = 0; k < 5; k++) record[k] = (double)block->header[k + 1];
    record[5] = (double)latency;
    record[6] = (double)compute;
    memcpy(record + RAW_SCALARS, block->values, 6 * (size_t)dof * sizeof(double));
    record[RAW_SCALARS + 6 * dof] = speed_override;
    *(uint32_t *)(slot + 8) = (uint32_t)ring->slot_bytes;
    atomic_store_explicit(sequence, (uint64_t)(2 * n + 2), memory_order_release);
    atomic_store_explicit(head, n + 1, memory_order_release);
}

/* Ask for SCHED_FIFO and the CPUs; what was granted goes into the statistics for Python to report. */
static void set_up_thread(plem_loop *loop) {
    plem_stats *stats = loop->stats;
    if (loop->priority > 0) {   /* 0: stay at the scheduling the thread was born with */
        struct sched_param parameters = {.sched_priority = loop->priority};
        int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &parameters);
        stats->sched_error = error;
        stats->policy = error == 0;
        stats->priority = error == 0 ? loop->priority : 0;
    }
    cpu_set_t cpus;
    if (loop->cpus) {
        CPU_ZERO(&cpus);
        for (int c = 0; c < 64; c++)
            if (loop->cpus >> c & 1) CPU_SET(c, &cpus);
        stats->affinity_error = pthread_setaffinity_np(pthread_self(), sizeof cpus, &cpus);
    }
    uint64_t granted = 0;
    if (pthread_getaffinity_np(pthread_self(), sizeof cpus, &cpus) == 0)
        for (int c = 0; c < 64; c++)
            if (CPU_ISSET(c, &cpus)) granted |= 1ULL << c;
    stats->cpus = granted;
    volatile uint8_t stack[64 * 1024];   /* touch the stack the cycle will use, so it faults in now */
    memset((uint8_t *)stack, 0, sizeof stack);
}

void *plem_loop_run(void *argument) {
    plem_loop *loop = argument;
    plem_stats *stats = loop->stats;
    plem_arm *arm = loop->arm;
    int dof = arm->settings.dof;
    int64_t period = loop->period_ns, previous_compute = 0;
    int64_t window_start = plem_now_ns(), window_overruns = 0, window_missed = 0, longest_run = 0;
    set_up_thread(loop);
    int64_t deadline = plem_now_ns() + period;
    while (!atomic_load_explicit(&loop->stop, memory_order_acquire)) {
        plem_sleep_until(deadline);
        int64_t woke = plem_now_ns();
        plem_arm_cycle(arm, &loop->bus, loop->slab, loop->block, loop->stream);
        if (loop->raw)
            plem_raw_write(loop->raw, loop->block, dof, woke - deadline, previous_compute, arm->override.factor);
        int64_t done = plem_now_ns();
        /* compute: the cycle's own work; the time on the wire is the master's to report */
        previous_compute = done - woke - (loop->bus.master ? loop->bus.master->wire_ns : 0);
        plem_series_add(&stats->latency, woke - deadline);
        plem_series_add(&stats->compute, previous_compute);
        atomic_store_explicit((_Atomic int64_t *)&stats->cycles, stats->cycles + 1, memory_order_release);
        deadline += period;
        if (done > deadline) {   /* skip every deadline already past, never burst to catch up */
            int64_t missed = (done - deadline) / period + 1;
            deadline += missed * period;
            stats->overruns++, stats->missed_periods += missed, stats->consecutive_overruns++;
            window_overruns++, window_missed += missed;
            if (stats->consecutive_overruns > longest_run) longest_run = stats->consecutive_overruns;
            if (stats->consecutive_overruns == loop->max_consecutive_overruns)
                plem_arm_fault(arm, PLEM_CAUSE_OVERRUN, (double)stats->consecutive_overruns,
                               (double)loop->max_consecutive_overruns);
        } else {
            stats->consecutive_overruns = 0;
        }
        if (done - window_start >= loop->window_ns) {
            if (window_overruns)
                plem_arm_report_overruns(arm, window_overruns, window_missed, longest_run, stats->overruns,
                                         (done - window_start) / 1000000);
            window_start = done, window_overruns = window_missed = longest_run = 0;
        }
    }
    return NULL;
}
