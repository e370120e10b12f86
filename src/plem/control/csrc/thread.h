/* The real-time thread's own state, held by the Python object that starts and stops it. */
#ifndef PLEM_THREAD_H
#define PLEM_THREAD_H

#include <stdatomic.h>
#include <stdint.h>

#include "plem_core.h"

typedef struct {
    plem_arm *arm;
    plem_bus bus;
    const plem_slab *slab;
    plem_state_block *block;
    plem_stream_block *stream;        /* NULL: no stream can be followed */
    plem_raw_ring *raw;               /* NULL: no rt_raw record */
    plem_stats *stats;
    int64_t period_ns;
    int64_t window_ns;                /* overruns are summarised once per window */
    uint64_t cpus;                    /* 0: wherever the machine puts it */
    int32_t priority;
    int32_t max_consecutive_overruns;
    atomic_int stop;
} plem_loop;

/* The thread's body: cycles until `stop`. */
void *plem_loop_run(void *loop);

#endif
