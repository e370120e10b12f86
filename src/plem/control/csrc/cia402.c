/* CiA402 power control: statusword decoding, the drive's state machine and the master's controlword choice. */
#include "plem_core.h"

#define FAULT_BIT 0x0008u
#define RESET_BIT 0x0080u
#define DISABLE_VOLTAGE 0x00u
#define SHUTDOWN 0x06u
#define SWITCH_ON 0x07u
#define ENABLE_OPERATION 0x0Fu
#define FAULT_RESET 0x80u

/* (mask, value, state) in the order of the CiA402 statusword table. */
static const struct { uint16_t mask, value; int state; } PATTERNS[] = {
    {0x4F, 0x00, PLEM_NOT_READY_TO_SWITCH_ON}, {0x4F, 0x40, PLEM_SWITCH_ON_DISABLED},
    {0x6F, 0x21, PLEM_READY_TO_SWITCH_ON},     {0x6F, 0x23, PLEM_SWITCHED_ON},
    {0x6F, 0x27, PLEM_OPERATION_ENABLED},      {0x6F, 0x07, PLEM_QUICK_STOP_ACTIVE},
    {0x4F, 0x0F, PLEM_FAULT_REACTION_ACTIVE},  {0x4F, 0x08, PLEM_FAULT},
};

/* The statusword a healthy drive under fieldbus control reports in each state (remote, voltage, no quick stop). */
static const uint16_t STATUSWORD[] = {0x0200, 0x0250, 0x0231, 0x0233, 0x0237, 0x0217, 0x021F, 0x0218};

int plem_decode_statusword(uint16_t statusword) {
    for (unsigned i = 0; i < sizeof PATTERNS / sizeof PATTERNS[0]; i++)
        if ((statusword & PATTERNS[i].mask) == PATTERNS[i].value) return PATTERNS[i].state;
    /* a pattern outside the profile never reads as enabled */
    return (statusword & FAULT_BIT) ? PLEM_FAULT : PLEM_NOT_READY_TO_SWITCH_ON;
}

uint16_t plem_statusword_of(int state) {
    return (state >= 0 && state <= PLEM_FAULT) ? STATUSWORD[state] : STATUSWORD[PLEM_FAULT];
}

/* Position of a state on the way up to operation enabled, -1 off that way. */
static int chain_index(int state) {
    switch (state) {
    case PLEM_SWITCH_ON_DISABLED: return 0;
    case PLEM_READY_TO_SWITCH_ON: return 1;
    case PLEM_SWITCHED_ON: return 2;
    case PLEM_OPERATION_ENABLED: return 3;
    default: return -1;
    }
}

static const uint16_t ENTERS[] = {DISABLE_VOLTAGE, SHUTDOWN, SWITCH_ON, ENABLE_OPERATION};

uint16_t plem_next_controlword(int state, int target, uint16_t previous) {
    if (state == PLEM_FAULT) return (previous & RESET_BIT) ? DISABLE_VOLTAGE : FAULT_RESET;
    int here = chain_index(state), there = chain_index(target);
    if (here < 0 || there < 0) return DISABLE_VOLTAGE;
    return ENTERS[here < there ? here + 1 : there];
}

int plem_drive_transition(int state, uint16_t controlword, uint16_t previous) {
    if (state == PLEM_NOT_READY_TO_SWITCH_ON) return PLEM_SWITCH_ON_DISABLED;
    if (state == PLEM_FAULT_REACTION_ACTIVE) return PLEM_FAULT;
    if (state == PLEM_FAULT)
        return ((controlword & RESET_BIT) && !(previous & RESET_BIT)) ? PLEM_SWITCH_ON_DISABLED : state;
    if (controlword & RESET_BIT) return state;
    if (!(controlword & 0x02)) return PLEM_SWITCH_ON_DISABLED;
    int running = state == PLEM_OPERATION_ENABLED || state == PLEM_QUICK_STOP_ACTIVE;
    if (!(controlword & 0x04)) return running ? PLEM_QUICK_STOP_ACTIVE : PLEM_SWITCH_ON_DISABLED;
    if (!(controlword & 0x01)) return state == PLEM_QUICK_STOP_ACTIVE ? state : PLEM_READY_TO_SWITCH_ON;
    if (state == PLEM_READY_TO_SWITCH_ON) return PLEM_SWITCHED_ON;
    if (controlword & 0x08)
        return (state == PLEM_SWITCHED_ON || running) ? PLEM_OPERATION_ENABLED : state;
    return state == PLEM_OPERATION_ENABLED ? PLEM_SWITCHED_ON : state;
}

void plem_power_init(plem_power *power, int dof) {
    power->dof = dof;
    for (int i = 0; i < PLEM_MAX_JOINTS; i++) {
        power->wanted[i] = PLEM_SWITCH_ON_DISABLED;
        power->reset[i] = 0;
        power->sent[i] = DISABLE_VOLTAGE;
    }
}

void plem_power_request(plem_power *power, int state) {
    for (int i = 0; i < power->dof; i++) power->wanted[i] = state;
}

void plem_power_request_reset(plem_power *power) {
    for (int i = 0; i < power->dof; i++) power->reset[i] = 1;
}

void plem_power_master_lost(plem_power *power) {
    plem_power_request(power, PLEM_SWITCH_ON_DISABLED);
    for (int i = 0; i < power->dof; i++) power->reset[i] = 0;
}

void plem_power_commands(plem_power *power, const int32_t *seen, uint16_t *out) {
    for (int i = 0; i < power->dof; i++) {
        uint16_t command;
        if (seen[i] == PLEM_FAULT) {
            /* a drive seen in fault is wanted down until enabled again; it gets one reset edge when asked */
            power->wanted[i] = PLEM_SWITCH_ON_DISABLED;
            if (!power->reset[i]) {
                command = DISABLE_VOLTAGE;
            } else {
                command = plem_next_controlword(PLEM_FAULT, PLEM_SWITCH_ON_DISABLED, power->sent[i]);
                power->reset[i] = command != FAULT_RESET;
            }
        } else {
            power->reset[i] = 0;
            command = plem_next_controlword(seen[i], power->wanted[i], power->sent[i]);
        }
        power->sent[i] = command;
        out[i] = command;
    }
}
