/* The monotonic clock the core reads and sleeps on: the cycle, the real-time thread and the EtherCAT keepalive. */
#ifndef PLEM_CLOCK_H
#define PLEM_CLOCK_H

#include <errno.h>
#include <stdint.h>
#include <time.h>

static inline int64_t plem_now_ns(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (int64_t)now.tv_sec * 1000000000LL + now.tv_nsec;
}

/* Sleep to an absolute CLOCK_MONOTONIC deadline (ns), resuming after signals. */
static inline void plem_sleep_until(int64_t deadline) {
    struct timespec at = {.tv_sec = deadline / 1000000000LL, .tv_nsec = deadline % 1000000000LL};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, NULL) == EINTR) {
    }
}

#endif
