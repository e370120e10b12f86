/* plem's compiled core: the structures it works on and the functions of one cycle.
 *
 * Every structure is plain data with fixed-width fields, so Python can hold it in its own memory (or shared
 * memory) and view it with numpy; module.c exports each field's offset, and plem.control.compiled checks its
 * own view against that table at import. Nothing here allocates, takes a lock or calls the Python C API.
 */
#ifndef PLEM_CORE_H
#define PLEM_CORE_H

#include <stdint.h>

/* Joints of the largest arm the core drives (the arms are 6 or 7 axes; the rest is headroom). */
#define PLEM_MAX_JOINTS 16

/* ---- CiA402 ------------------------------------------------------------------------------------------ */

/* Power states of a CiA402 drive, numbered as plem.fieldbus.bus.DriveState. */
enum plem_drive_state {
    PLEM_NOT_READY_TO_SWITCH_ON = 0,
    PLEM_SWITCH_ON_DISABLED = 1,
    PLEM_READY_TO_SWITCH_ON = 2,
    PLEM_SWITCHED_ON = 3,
    PLEM_OPERATION_ENABLED = 4,
    PLEM_QUICK_STOP_ACTIVE = 5,
    PLEM_FAULT_REACTION_ACTIVE = 6,
    PLEM_FAULT = 7,
};

/* Modes of operation (0x6060) the core uses. */
enum plem_operation_mode { PLEM_CSP = 8, PLEM_CSV = 9, PLEM_CST = 10 };

int plem_decode_statusword(uint16_t statusword);
uint16_t plem_statusword_of(int state);
uint16_t plem_next_controlword(int state, int target, uint16_t previous);
int plem_drive_transition(int state, uint16_t controlword, uint16_t previous);

/* The master's side of CiA402 power control: which controlword moves each drive toward the wanted state. */
typedef struct {
    int32_t dof;
    int32_t pad;
    int32_t wanted[PLEM_MAX_JOINTS];    /* the state asked of each drive */
    uint8_t reset[PLEM_MAX_JOINTS];     /* a fault-reset edge still to send */
    uint16_t sent[PLEM_MAX_JOINTS];     /* the controlword each drive got last */
} plem_power;

void plem_power_init(plem_power *power, int dof);
void plem_power_request(plem_power *power, int state);
void plem_power_request_reset(plem_power *power);
void plem_power_master_lost(plem_power *power);
/* This cycle's controlwords into `out` for drives last seen in the states `seen`. */
void plem_power_commands(plem_power *power, const int32_t *seen, uint16_t *out);

/* ---- rigid-body model --------------------------------------------------------------------------------- */

enum plem_joint_kind { PLEM_REVOLUTE = 0, PLEM_PRISMATIC = 1 };

/* An arm's kinematic tree with its inertias, joints in topological order (a parent before its children):
 * what pinocchio's model holds for single-axis joints, fixed links already merged into their parents. */
typedef struct {
    int32_t dof;
    int32_t pad;
    double gravity[3];                        /* m/s² in the base frame */
    int32_t parent[PLEM_MAX_JOINTS];          /* index of the parent joint, -1 for the base */
    int32_t kind[PLEM_MAX_JOINTS];            /* enum plem_joint_kind */
    int32_t arm_index[PLEM_MAX_JOINTS];       /* where this joint's value sits in the arm's joint order */
    int32_t pad2[PLEM_MAX_JOINTS];
    double axis[PLEM_MAX_JOINTS][3];          /* unit axis in the joint frame */
    double rotation[PLEM_MAX_JOINTS][9];      /* joint frame in the parent's frame at q = 0, row-major */
    double translation[PLEM_MAX_JOINTS][3];
    double mass[PLEM_MAX_JOINTS];             /* the body after the joint: kg */
    double com[PLEM_MAX_JOINTS][3];           /* centre of mass in the joint frame, m */
    double inertia[PLEM_MAX_JOINTS][9];       /* rotational inertia about the centre of mass, kg·m², row-major */
} plem_model;

/* Vectors are in the arm's joint order. */
void plem_inverse_dynamics(const plem_model *model, const double *q, const double *v, const double *a, double *tau);
void plem_gravity(const plem_model *model, const double *q, double *tau);
void plem_forward_dynamics(const plem_model *model, const double *q, const double *v, const double *tau, double *a);

/* ---- motions ----------------------------------------------------------------------------------------- */

/* Coefficients per segment and joint, lowest order first: enough for a quintic. */
#define PLEM_ORDER 6
/* Segments of the longest stop: three phases per joint. */
#define PLEM_STOP_SEGMENTS (3 * PLEM_MAX_JOINTS)

/* A planned motion, sampled in place: knot times (segments + 1), per segment and joint the coefficients of a
 * polynomial in the time since the segment's start (segments × PLEM_ORDER × dof), and the state after the last
 * knot (position, velocity, acceleration rows of dof). `cursor` is the segment of the last sample. */
typedef struct {
    const double *knots;
    const double *coefficients;
    const double *final;
    int32_t segments;
    int32_t dof;
    int32_t cursor;
} plem_motion;

/* Position, velocity and acceleration at `t` s after the start into out (3 × dof); 1 once `t` is at or past the end. */
int plem_motion_sample(plem_motion *motion, double t, double *out);

/* The quickest jerk-limited stop of every joint from (p, v, a) to rest within its acceleration and jerk limits
 * (inf: unlimited), each joint on its own: knots (PLEM_STOP_SEGMENTS + 1), coefficients (PLEM_STOP_SEGMENTS ×
 * PLEM_ORDER × dof) and the final state (3 × dof). Returns the number of segments. */
int plem_plan_stop(int dof, const double *p, const double *v, const double *a, const double *max_acceleration,
                   const double *max_jerk, double *knots, double *coefficients, double *final);

/* ---- the simulated arm -------------------------------------------------------------------------------- */

/* Simulated CiA402 drives, encoders and joints: the bus of bus:=mock and the drives of the virtual network.
 * Settings are written once by Python; io_* is the process data a master reads and writes. */
typedef struct {
    /* settings */
    int32_t dof;
    int32_t dynamics;                     /* 1: rigid body (model); 0: first-order follower */
    double dt;                            /* cycle time, s */
    double omega;                         /* servo bandwidth, rad/s */
    double follow;                        /* follower: exp(-dt / time constant) */
    double deceleration;                  /* quick-stop ramp, rad/s² */
    double pad0;
    double counts[PLEM_MAX_JOINTS];       /* encoder counts per joint radian (signed) */
    double raw_zero[PLEM_MAX_JOINTS];     /* raw encoder reading at q = 0 */
    double friction[PLEM_MAX_JOINTS];     /* viscous, N·m·s/rad */
    double effort[PLEM_MAX_JOINTS];       /* torque a drive can apply, inf when unlimited */
    double lower[PLEM_MAX_JOINTS];        /* hard stops, ±inf when none */
    double upper[PLEM_MAX_JOINTS];
    double max_error[PLEM_MAX_JOINTS];    /* position error at which the servo drives the joint at its speed limit */
    /* the simulated joints */
    double q[PLEM_MAX_JOINTS];
    double v[PLEM_MAX_JOINTS];
    double tau[PLEM_MAX_JOINTS];          /* torque the drives apply */
    double external[PLEM_MAX_JOINTS];     /* pushes, N·m */
    double stop_q[PLEM_MAX_JOINTS];       /* quick-stop ramp of each stopping drive */
    double stop_v[PLEM_MAX_JOINTS];
    int64_t spike[PLEM_MAX_JOINTS];       /* counts added to the next reading, once */
    uint8_t stuck[PLEM_MAX_JOINTS];       /* jammed joints */
    uint8_t latched[PLEM_MAX_JOINTS];     /* faults a reset does not clear */
    uint8_t stopping[PLEM_MAX_JOINTS];    /* drives that were quick-stopping last cycle */
    uint8_t pad1[PLEM_MAX_JOINTS];
    /* the drives */
    int32_t state[PLEM_MAX_JOINTS];       /* enum plem_drive_state */
    uint16_t statusword[PLEM_MAX_JOINTS];
    uint16_t error_code[PLEM_MAX_JOINTS];
    uint16_t controlword[PLEM_MAX_JOINTS]; /* the last one each drive received */
    uint16_t pad2[PLEM_MAX_JOINTS];
    /* communication */
    int32_t lost;                         /* 1 while the exchange is dropped */
    int32_t pad3;
    int64_t lost_reads;                   /* reads still to drop; -1 until restored */
    int64_t lost_frames;
    /* process data: outputs written by the master */
    int64_t io_target_position[PLEM_MAX_JOINTS];
    int64_t io_velocity_offset[PLEM_MAX_JOINTS];
    double io_torque_offset[PLEM_MAX_JOINTS];   /* N·m at the joint */
    int8_t io_mode[PLEM_MAX_JOINTS];
    uint8_t pad4[PLEM_MAX_JOINTS];
    /* process data: inputs read by the master */
    int64_t io_position[PLEM_MAX_JOINTS];
    int64_t io_velocity[PLEM_MAX_JOINTS];
    double io_torque[PLEM_MAX_JOINTS];
    uint16_t io_statusword[PLEM_MAX_JOINTS];
    uint16_t io_error_code[PLEM_MAX_JOINTS];
    /* the master side when the simulated arm is the bus itself (bus:=mock) */
    plem_power power;
    /* scratch of one step */
    double scratch[8][PLEM_MAX_JOINTS];
    plem_model model;
} plem_sim;

/* The bus's read: encoder counts, torques, statuswords and error codes into io_*; 0 while communication is lost. */
int plem_sim_read(plem_sim *sim);
/* The bus's write: controlwords from the power sequencer (or a quick stop while lost), then one cycle. */
void plem_sim_write(plem_sim *sim);
/* Be the drives of a real master: take its controlwords and advance one cycle. */
void plem_sim_serve(plem_sim *sim, const uint16_t *controlwords);
/* Drives that no longer hear their master quick-stop; 1 when a drive changed state. */
int plem_sim_quick_stop(plem_sim *sim);
/* One drive faults with `error_code`; a latched fault survives resets. */
void plem_sim_fault(plem_sim *sim, int drive, uint16_t error_code, int latched);
/* Every drive not in fault switches off, and the master asks for that too. */
void plem_sim_power_off(plem_sim *sim);

#endif
