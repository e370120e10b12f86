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
/* The Jacobian (6 × dof row-major: linear then angular rows, base frame; columns in arm order) of a point given in
 * the frame of joint `body` (topological index). */
void plem_point_jacobian(const plem_model *model, const double *q, int body, const double *point, double *jacobian);
/* The joint torques of a wrench (force then torque, base frame) applied at a point of joint `body`'s frame. */
void plem_wrench_torques(const plem_model *model, const double *q, int body, const double *point,
                         const double *wrench, double *tau);
/* The wrench (force then torque, base frame) at the last joint's origin that best explains joint torques `tau`. */
void plem_tool_wrench(const plem_model *model, const double *q, const double *tau, double *wrench);

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

/* ---- streaming: an online jerk-limited follower ------------------------------------------------------------ */

/* fmin, fmax and a clamp without the NaN rules that keep the compiler from inlining fmin and fmax (a call each, in
 * loops over the joints every cycle); a NaN x still clamps to `low`, as fmax gives. */
static inline double plem_lesser(double a, double b) { return a < b ? a : b; }
static inline double plem_greater(double a, double b) { return a > b ? a : b; }
static inline double plem_clamp(double x, double low, double high) {
    return plem_lesser(plem_greater(x, low), high);
}

/* What the follower works toward this cycle and within which limits: arrays over the joints. */
typedef struct {
    const double *target_position;   /* positions to come to rest at (moving at target_velocity); NULL: none */
    const double *target_velocity;   /* the targets' own velocities, or without positions the velocities to reach;
                                        NULL: at rest */
    const double *max_velocity, *max_acceleration, *max_jerk;
    double share;                    /* of those limits the follower uses */
    double speed;                    /* of the velocity it uses, the share not to pass (the speed override) */
    const double *low, *high;        /* the positions to stop within */
} plem_follow_targets;

/* Each of n joints' next command (p, v, a arrays) one cycle on, toward its target position or velocity, never
 * faster than its speed, past its limits or outside [low, high]: a jump or a gap in the targets is smoothed, never
 * passed on. */
void plem_follow(int n, double *p, double *v, double *a, const plem_follow_targets *t, double dt);

/* The rate at the end of the coming cycle that brings `value` (now changing at `rate`) to `goal` as fast as
 * |rate| <= max_rate and |change of rate| <= max_change allow, landing with the rate at zero: deadbeat for the
 * cycle's trapezoidal integration, so it settles in two cycles instead of buzzing. The follower's inner law (value a
 * velocity, rate an acceleration), and the speed override's (value the factor). */
double plem_approach(double value, double rate, double goal, double max_rate, double max_change, double dt);

enum plem_stream_kind { PLEM_STREAM_POSITION = 1, PLEM_STREAM_VELOCITY = 2 };
enum plem_stream_state { PLEM_STREAM_NONE = 0, PLEM_STREAM_FOLLOWING = 1, PLEM_STREAM_TIMED_OUT = 2 };

/* The stream block: a client writes samples into it (a seqlock and a checksum, so a torn or mixed sample is never
 * used), the core reads the newest each cycle and writes back what it used. */
typedef struct {
    uint64_t sequence;               /* odd while a sample is written */
    uint64_t session;                /* the stream the sample belongs to: its start request's token */
    uint64_t count;                  /* samples written in this session */
    int64_t kind;                    /* enum plem_stream_kind */
    int64_t stamp_ns;                /* the writer's CLOCK_MONOTONIC when it wrote the sample */
    uint64_t checksum;               /* xor of session, count, kind, stamp and every target's bits */
    uint64_t pad0[2];
    double target[PLEM_MAX_JOINTS];  /* rad, or rad/s */
    /* written by the core, on cache lines of their own (checked in module.c) */
    uint64_t used_session;           /* the stream the core follows, 0 for none */
    uint64_t used_count;             /* the last sample a cycle used */
    int64_t used_cycle;
    int64_t latency_ns;              /* that sample's stamp to the cycle that first used it */
    int32_t state;                   /* enum plem_stream_state */
    int32_t pad1;
    double speed_override;           /* the factor in force */
    double override_target;          /* the factor asked for */
    double external[PLEM_MAX_JOINTS]; /* estimated external joint torque (N·m): the model's effort less the measured */
    double wrench[6];                /* the same as a wrench at the flange (N, N·m, base frame) */
} plem_stream_block;

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
    double push[6];                       /* a wrench (force then torque, base frame) on push_body at push_point */
    double push_point[3];                 /* in push_body's joint frame, m */
    int32_t push_body;                    /* topological joint index whose body is pushed; -1: none */
    int32_t payload_pending;              /* 1: payload_body replaces the last body's inertials at the next step */
    double payload_body[13];              /* mass, centre of mass (3), inertia about it (9, row-major) */
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
    uint32_t digital_inputs[PLEM_MAX_JOINTS]; /* what each drive reports as 0x60FD, set from outside */
    /* communication */
    int32_t lost;                         /* 1 while the exchange is dropped */
    int32_t answered;                     /* the last read got an answer */
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
/* A master's exchange with the simulated arm: its controlwords (a quick stop while communication is lost),
 * then one cycle. */
void plem_sim_exchange(plem_sim *sim, const uint16_t *controlwords);
/* Drives that no longer hear their master quick-stop; 1 when a drive changed state. */
int plem_sim_quick_stop(plem_sim *sim);
/* One drive faults with `error_code`; a latched fault survives resets. */
void plem_sim_fault(plem_sim *sim, int drive, uint16_t error_code, int latched);
/* Every drive not in fault switches off, and the master asks for that too. */
void plem_sim_power_off(plem_sim *sim);


/* ---- the arm's cycle ---------------------------------------------------------------------------------- */

enum plem_mode { PLEM_IDLE = 0, PLEM_HOLD = 1, PLEM_TRAJECTORY = 2, PLEM_FREE_DRIVE = 3, PLEM_FAULTED = 4 };

/* Requests from Python (the command ring). */
enum plem_op {
    PLEM_OP_SET_MODE = 1, PLEM_OP_START = 2, PLEM_OP_STOP = 3, PLEM_OP_RESET = 4,
    PLEM_OP_STREAM = 5,              /* follow the stream block's samples (cycles: the timeout) */
    PLEM_OP_OVERRIDE = 6,            /* the speed override asked for (value, 0..1) */
    PLEM_OP_REACT = 7,               /* arm the reaction written into reactions[slot] */
    PLEM_OP_UNREACT = 8,             /* remove reactions[slot] */
    PLEM_OP_PAYLOAD = 9,             /* the last body's inertials become body[0..12]: mass, centre of mass, inertia */
};

/* Answers to requests (the outcome ring): a stage and, for refusals and ends, a code with its numbers. */
enum plem_stage { PLEM_ACCEPTED = 1, PLEM_REJECTED = 2, PLEM_FINISHED = 3 };
enum plem_answer {
    PLEM_ANSWER_MODE = 1,          /* finished: mode reached (mode) */
    PLEM_ANSWER_DONE,              /* finished: a stop request, nothing to report */
    PLEM_ANSWER_NOT_HOLDING,       /* rejected start: mode (mode), a mode change pending (detail) */
    PLEM_ANSWER_STALE,             /* rejected start: planned from an outdated state */
    PLEM_ANSWER_MODE_PENDING,      /* rejected set_mode: a mode change to (detail) is in progress */
    PLEM_ANSWER_TRANSITION,        /* rejected set_mode: not allowed from (mode) to (detail) */
    PLEM_ANSWER_MOVING,            /* rejected: action (detail) needs standstill; joint moving at values[0], or a
                                      motion runs (joint -1) */
    PLEM_ANSWER_ENABLE_TIMEOUT,    /* rejected: drives not enabled in time; values[0] the drive states, 4 bits each */
    PLEM_ANSWER_RESET_NO_BUS,      /* rejected reset: bus communication lost */
    PLEM_ANSWER_FAULTED,           /* rejected: the robot faulted while the mode change was pending */
    PLEM_ANSWER_SUCCEEDED,         /* motion finished: reached its goal */
    PLEM_ANSWER_GOAL_VIOLATED,     /* motion aborted: joint values[0] rad from goal after goal_time */
    PLEM_ANSWER_PATH_VIOLATED,     /* motion aborted: joint values[0] rad from the path, tolerance values[1] */
    PLEM_ANSWER_FAULT_ABORTED,     /* motion aborted: the robot faulted */
    PLEM_ANSWER_PREEMPTED,         /* motion replaced by a newer one */
    PLEM_ANSWER_CANCELED,          /* motion canceled */
    PLEM_ANSWER_INVALID_SLOT,      /* rejected start: the slot does not hold the announced motion */
    PLEM_ANSWER_UNKNOWN_OP,        /* rejected: not a request the core knows */
    PLEM_ANSWER_STREAMING,         /* rejected start: a stream runs (stop it first) */
    PLEM_ANSWER_STREAM_TIMED_OUT,  /* stream ended: no sample for (detail) cycles, the arm came to rest */
    PLEM_ANSWER_INVALID_VALUE,     /* rejected: a number outside its range (values[0]) */
    PLEM_ANSWER_REACTED,           /* motion ended by a reaction (detail: its slot) */
    PLEM_ANSWER_MALFORMED_REACTION, /* rejected arming: the slot's condition is not a whole program (detail: slot) */
};

/* What happened in the loop (the event ring). */
enum plem_event_kind {
    PLEM_EVENT_MODE_CHANGED = 1, PLEM_EVENT_FAULT, PLEM_EVENT_FAULT_CLEARED, PLEM_EVENT_MOTION_STARTED,
    PLEM_EVENT_MOTION_FINISHED, PLEM_EVENT_COMMAND_REJECTED, PLEM_EVENT_WARNING,
    PLEM_EVENT_OVERRUN,              /* a window with overruns: values overruns, skipped, longest run, total; detail ms */
    PLEM_EVENT_REACTION,             /* a reaction fired: token its own, joint its slot, detail its action, values[0]
                                        the first measured quantity, values[1] its threshold */
};
enum plem_cause {
    /* mode changes */
    PLEM_CAUSE_SET_MODE_IDLE = 1, PLEM_CAUSE_SET_MODE_FREE_DRIVE, PLEM_CAUSE_SET_MODE_HOLD, PLEM_CAUSE_DRIVES_ENABLED,
    PLEM_CAUSE_MOTION_STARTED, PLEM_CAUSE_MOTION_FINISHED,
    /* faults: joint and values name what was breached */
    PLEM_CAUSE_DRIVE_FAULT, PLEM_CAUSE_DRIVE_DISABLED, PLEM_CAUSE_ENCODER_JUMP, PLEM_CAUSE_POSITION_LIMIT,
    PLEM_CAUSE_VELOCITY_LIMIT, PLEM_CAUSE_TRACKING_ERROR, PLEM_CAUSE_COMMUNICATION_LOST, PLEM_CAUSE_INVALID_COMMAND,
    PLEM_CAUSE_COMMAND_POSITION, PLEM_CAUSE_COMMAND_VELOCITY, PLEM_CAUSE_COMMAND_ACCELERATION,
    PLEM_CAUSE_COMMAND_JERK, PLEM_CAUSE_OVERRUN, PLEM_CAUSE_INTERNAL_ERROR,
    /* the rest */
    PLEM_CAUSE_RESET, PLEM_CAUSE_BRAKES_ENGAGED, PLEM_CAUSE_ENABLE_TIMEOUT,
    PLEM_CAUSE_CONTACT,              /* fault: joint's estimated external torque values[0] past its threshold values[1] */
    PLEM_CAUSE_REACTION,
};

/* Reactions: conditions over what the core measures, evaluated every cycle, each with an action. A condition is a
 * program in postfix: comparisons push a truth, AND/OR/NOT combine the top ones. */
#define PLEM_REACTIONS 16
#define PLEM_UNSETTLED_S 0.02      /* s without the external-torque estimate after a stale bus answer */
#define PLEM_REACTION_TERMS 16
enum plem_measure {
    PLEM_MEASURE_POSITION = 1, PLEM_MEASURE_VELOCITY, PLEM_MEASURE_EFFORT, PLEM_MEASURE_EXTERNAL_TORQUE,
    PLEM_MEASURE_WRENCH, PLEM_MEASURE_FOLLOWING_ERROR, PLEM_MEASURE_MOTION_TIME, PLEM_MEASURE_DRIVE_STATE,
    PLEM_MEASURE_DIGITAL_INPUT,      /* index: joint · 32 + bit of the drive's 0x60FD digital inputs */
    PLEM_MEASURES                    /* one past the last */
};
enum plem_term_op { PLEM_TERM_ABOVE = 1, PLEM_TERM_BELOW, PLEM_TERM_EQUAL, PLEM_TERM_AND, PLEM_TERM_OR, PLEM_TERM_NOT };
enum plem_reaction_action {
    PLEM_REACT_STOP = 1,             /* end the running motion with the quickest stop */
    PLEM_REACT_HOLD,                 /* pause on the path: the speed override's target becomes 0 */
    PLEM_REACT_FREE_DRIVE,           /* end the running motion and switch to free drive */
    PLEM_REACT_MOVE,                 /* follow a joint target (target) from where the command is, then hold */
    PLEM_REACT_RECORD,               /* an event only */
};
typedef struct {
    int16_t op;                      /* enum plem_term_op */
    int16_t measure;                 /* comparisons: enum plem_measure */
    int16_t index;                   /* comparisons: the joint, the wrench component, or joint · 32 + bit */
    int16_t pad;
    double threshold;
} plem_term;
typedef struct {
    uint64_t token;                  /* names the reaction in events */
    uint64_t motion;                 /* 0: standing until removed; else the motion it belongs to, removed with it */
    int32_t armed;                   /* the core evaluates it (set by PLEM_OP_REACT, cleared on removal) */
    int32_t terms;
    int32_t action;                  /* enum plem_reaction_action */
    int32_t once;                    /* removed once it fired; else it fires on each rise of its condition */
    plem_term term[PLEM_REACTION_TERMS];
    double target[PLEM_MAX_JOINTS];  /* move: the joint target */
} plem_reaction;

/* A condition of PLEM_REACTION_TERMS terms compares at most this many quantities: each comparison but the first
 * needs a binary combination. */
#define PLEM_CONDITION_COMPARISONS ((PLEM_REACTION_TERMS + 1) / 2)

/* An armed reaction as the cycle walks it: where its comparisons are in the program, and its condition as a truth
 * table over them, worked out when armed. */
typedef struct {
    uint64_t table[4];               /* bit i of 256: the condition when comparison j's truth is bit j of i */
    int16_t start;                   /* its first comparison in the program: the one its events report */
    int16_t comparisons;
    int32_t pad;
} plem_armed;

/* One comparison of an armed condition. */
typedef struct {
    int8_t holds_if;                 /* bit 0: true when above the threshold, bit 1: below, bit 2: equal */
    int8_t measure;                  /* enum plem_measure */
    int16_t index;
    int32_t pad;
    double threshold;
} plem_comparison;

/* The armed reactions' comparisons, laid end to end (a cycle reads a few lines, not a slot each); rebuilt
 * whenever a reaction is armed or disarmed. `uses` has bit m set when a comparison reads measure m. */
typedef struct {
    plem_armed slot[PLEM_REACTIONS];
    plem_comparison comparison[PLEM_REACTIONS * PLEM_CONDITION_COMPARISONS];
    uint32_t uses;
    uint32_t bound;                  /* bit k: armed slot k belongs to a motion */
    uint32_t was_true;               /* bit k: slot k's condition last cycle (an action starts on a rise) */
    int32_t pad;
} plem_program;

#define PLEM_COMMAND_SLOTS 64
#define PLEM_OUTCOME_SLOTS 256
#define PLEM_EVENT_SLOTS 256
/* Requests the core takes per cycle at most. */
#define PLEM_COMMANDS_PER_CYCLE 8

typedef struct {
    uint64_t token;
    int32_t op;                      /* enum plem_op */
    int32_t mode;                    /* set_mode: the mode asked for */
    int32_t slot;                    /* start: the slab slot holding the motion */
    int32_t segments;                /* start: its segment count */
    uint64_t basis;                  /* start: the basis generation it was planned from */
    int64_t activation;              /* start: the cycle it takes over a running motion, -1 at once */
    uint64_t goal;                   /* stop: only this motion's token (0: whatever runs) */
    int32_t has_path, has_goal;      /* start: which tolerances are checked */
    double goal_time;                /* start: s to settle after the end (inf: forever) */
    double stopped_velocity;         /* start: rad/s below which a joint counts as stopped */
    double path[PLEM_MAX_JOINTS];    /* rad; inf leaves a joint unchecked */
    double goal_tolerance[PLEM_MAX_JOINTS];
    double peaks[3][PLEM_MAX_JOINTS]; /* start: the motion's largest |velocity|, |acceleration|, |jerk| (own time) */
    double value;                    /* override: the factor */
    double body[13];                 /* payload: mass, centre of mass (3), inertia about it (9, row-major) */
    int64_t cycles;                  /* stream: cycles without a sample before it stops */
} plem_command;

typedef struct {
    uint64_t token;
    int64_t cycle;
    int32_t stage;                   /* enum plem_stage */
    int32_t answer;                  /* enum plem_answer */
    int32_t mode;
    int32_t detail;
    int32_t joint;
    int32_t pad;
    double values[2];
} plem_outcome;

typedef struct {
    int64_t cycle;
    int64_t monotonic_ns;
    uint64_t token;                  /* the motion's, for motion events */
    int32_t kind;                    /* enum plem_event_kind */
    int32_t cause;                   /* enum plem_cause */
    int32_t mode;
    int32_t previous_mode;           /* -1 when the mode did not change */
    int32_t joint;                   /* -1 when no joint is concerned */
    int32_t detail;                  /* an answer code, a limit row, a statusword */
    double values[4];
} plem_event;

/* A single-producer, single-consumer ring index: the producer advances head, the consumer tail. */
typedef struct {
    uint64_t head;
    uint64_t pad0[7];
    uint64_t tail;
    uint64_t pad1[7];
    uint64_t dropped;                /* records the producer could not put (the consumer fell behind) */
    uint64_t pad2[7];
} plem_ring;

/* Fixed settings of one arm (SI units), written by Python before the first cycle. */
typedef struct {
    int32_t dof;
    int32_t bus;                     /* 0: process data exchanged by the caller; 1: the core steps the bus */
    double dt;
    double tracking_tolerance;       /* rad between command and measurement before a fault */
    double velocity_margin;          /* measured |v| may exceed max_velocity by this factor */
    double position_margin;          /* rad a measured position may pass a limit */
    double standstill_velocity;      /* rad/s below which the arm stands still */
    double command_tolerance;        /* relative slack for commanded derivatives */
    int64_t enable_timeout_cycles;
    double counts_per_radian[PLEM_MAX_JOINTS];
    int64_t offsets[PLEM_MAX_JOINTS];
    double min_position[PLEM_MAX_JOINTS];
    double max_position[PLEM_MAX_JOINTS];
    double max_velocity[PLEM_MAX_JOINTS];
    double max_acceleration[PLEM_MAX_JOINTS];
    double max_jerk[PLEM_MAX_JOINTS];
    double max_effort[PLEM_MAX_JOINTS];
    double damping[PLEM_MAX_JOINTS];  /* free drive, N·m·s/rad */
    double friction[PLEM_MAX_JOINTS]; /* viscous, N·m·s/rad: part of the model's effort the external torque is from */
    double contact_threshold[PLEM_MAX_JOINTS]; /* N·m of estimated external torque that stops the arm; inf: off */
} plem_settings;

/* Where a new motion starts: the held position, or a running motion (a slab slot, or the core's stop) whose own
 * time is `time` at cycle `start_cycle` and advances by `rate` × dt a cycle. Its generation changes whenever it
 * does; a start planned from another generation is stale. While `ramping` (the speed override changes) a running
 * motion's future is not known ahead, nor is a stream's, and no start takes them over. */
#define PLEM_STOP_SLOT (-2)
#define PLEM_STREAM_SLOT (-3)
typedef struct {
    uint64_t sequence;               /* seqlock: odd while written */
    uint64_t generation;
    int32_t slot;                    /* -1: holding; PLEM_STOP_SLOT: the core's stop; PLEM_STREAM_SLOT; a slab slot */
    int32_t segments;
    int64_t start_cycle;
    double time;
    double rate;
    int32_t ramping;
    int32_t pad;
    double hold_position[PLEM_MAX_JOINTS];
} plem_basis;

/* The speed override: a running slab motion's own time advances by `factor` × dt a cycle, the factor moving toward
 * `target` only as fast as keeps every limit wherever on the motion the arm is (see arm.c). */
typedef struct {
    double target;                   /* asked for, 0..1 */
    double factor;                   /* in force this cycle */
    double rate;                     /* the factor's rate of change, 1/s */
    double time;                     /* the running motion's own time at this cycle, s */
    double peaks[3][PLEM_MAX_JOINTS]; /* the running motion's largest |velocity|, |acceleration|, |jerk| */
} plem_override;

/* The stream the core follows. */
typedef struct {
    uint64_t session;                /* the stream's token; 0: none */
    int64_t timeout_cycles;
    int64_t last_cycle;              /* when the last new sample arrived */
    uint64_t last_count;
    int64_t last_stamp;
    int64_t feed_until;              /* the cycle until which `feed` holds: one sample period after the last */
    int32_t kind;                    /* of the last sample */
    int32_t timed_out;
    int32_t internal;                /* a reaction's move: the target is fixed, no samples, no timeout */
    int32_t pad;
    double target[PLEM_MAX_JOINTS];
    double feed[PLEM_MAX_JOINTS];    /* the targets' velocity, from the last two position samples */
} plem_stream;

/* The arm: settings, the state of its cycle, and its rings. */
typedef struct {
    plem_settings settings;
    plem_model model;                /* gravity in free drive */
    /* process data, in counts at the bus boundary */
    int64_t io_position[PLEM_MAX_JOINTS];
    int64_t io_velocity[PLEM_MAX_JOINTS];
    double io_torque[PLEM_MAX_JOINTS];
    uint16_t io_statusword[PLEM_MAX_JOINTS];
    uint16_t io_error_code[PLEM_MAX_JOINTS];
    int64_t io_target_position[PLEM_MAX_JOINTS];
    int64_t io_velocity_offset[PLEM_MAX_JOINTS];
    double io_torque_offset[PLEM_MAX_JOINTS];
    int8_t io_mode[PLEM_MAX_JOINTS];
    uint8_t pad0[PLEM_MAX_JOINTS];
    uint32_t io_digital_inputs[PLEM_MAX_JOINTS]; /* 0x60FD of the drives that report it */
    uint32_t io_inputs_reported;     /* bit j: drive j reports its digital inputs */
    int32_t pad6;
    int32_t io_answered;             /* the bus answered this cycle's read */
    int32_t power_wanted;            /* what the drives were last asked for: switch on disabled or operation enabled */
    uint64_t power_requests;         /* power requests so far (a Python bus passes each one on as enable/disable) */
    uint64_t power_resets;           /* fault-reset edges asked for so far */
    plem_power power;                /* the controlwords, when the core is the master */
    /* the cycle */
    int64_t cycle;
    int32_t mode;                    /* enum plem_mode */
    int32_t fault_cause;             /* enum plem_cause of the current fault, 0 when none */
    int32_t communication_ok;
    int32_t have_previous;
    int32_t braking;                 /* faulted and the drives could not hold the arm: they are off */
    int32_t pad1;
    double work[6][PLEM_MAX_JOINTS]; /* position, velocity, effort, command position/velocity/acceleration */
    double previous_position[PLEM_MAX_JOINTS];
    double previous_acceleration[PLEM_MAX_JOINTS];
    double torque[PLEM_MAX_JOINTS];
    double reach[2][PLEM_MAX_JOINTS];  /* lowest and highest position allowed: the limits, widened to where the
                                          command was at the last basis (an arm outside its range may come back) */
    /* the running motion */
    int32_t active;                  /* a motion runs */
    int32_t active_ended;
    int32_t active_slot;
    int32_t active_segments;
    uint64_t active_token;           /* 0 for the core's own stop */
    uint64_t last_start;             /* the newest start request taken (tokens rise in the order requests are
                                        queued): a reaction bound to a later motion waits for it */
    int64_t active_start_cycle;
    int64_t settle_deadline;         /* -1 until the motion's end */
    int32_t active_cursor;
    int32_t active_has_path, active_has_goal, pad2;
    double active_goal_time, active_stopped_velocity;
    double active_path[PLEM_MAX_JOINTS];
    double active_goal[PLEM_MAX_JOINTS];
    double active_final[3][PLEM_MAX_JOINTS];
    /* a mode change waiting for the drives */
    int32_t pending;
    int32_t pending_target;
    int64_t pending_deadline;
    uint64_t pending_token;          /* 0: no one waits (a reset's enable answers the reset) */
    int32_t pending_enable_sent;
    int32_t pad3;
    /* the core's stop, a motion like the others */
    double stop_knots[PLEM_STOP_SEGMENTS + 1];
    double stop_coefficients[PLEM_STOP_SEGMENTS * PLEM_ORDER * PLEM_MAX_JOINTS];
    double stop_final[3 * PLEM_MAX_JOINTS];
    int32_t stop_segments;
    int32_t pad4;
    plem_basis basis;
    plem_override override;
    plem_stream stream;
    /* what the arm feels: the model's effort for the command less the measured (estimated when the model's
     * effort is known: drives enabled, not in free drive) */
    int32_t feeling;                 /* 1 while the estimate below is current */
    uint32_t reacting;               /* bit k set while reactions[k] is armed */
    int32_t unsettled;               /* cycles until the estimate is trusted again after a bus answer was stale */
    int32_t commanded;               /* the command rows hold this cycle's command (else the previous cycle's) */
    double external[PLEM_MAX_JOINTS];
    double wrench[6];
    plem_reaction reactions[PLEM_REACTIONS];
    plem_program program;
    /* rings */
    plem_ring commands_index;
    plem_command commands[PLEM_COMMAND_SLOTS];
    plem_ring outcomes_index;
    plem_outcome outcomes[PLEM_OUTCOME_SLOTS];
    plem_ring events_index;
    plem_event events[PLEM_EVENT_SLOTS];
} plem_arm;

/* The motion slab the core samples started motions from (the layout of plem.ipc.motion_slab). */
typedef struct {
    const uint8_t *base;
    int64_t size;
} plem_slab;

/* The state block the cycle publishes (the seqlock of plem.control.state): int64 header, float64 rows. */
typedef struct {
    int64_t *header;
    double *values;
} plem_state_block;

/* The bus a cycle steps itself: the simulated arm, or an EtherCAT master (master.h); with neither, the caller
 * exchanges process data through the arm's io_* fields. */
struct plem_master;
typedef struct {
    plem_sim *sim;
    struct plem_master *master;
} plem_bus;

/* The master's read: the answer to last cycle's frame into the arm's io_* (the last good inputs stand in for a
 * bad answer); 0 once bad_cycles_to_fault answers in a row were bad. */
int plem_master_read(struct plem_master *master, plem_arm *arm);
/* Whether the last read's inputs are this cycle's answer (0 while the last good inputs stand in for a bad one). */
int plem_master_fresh(const struct plem_master *master);
/* The master's write: the arm's targets and `controlwords` into the outputs, and the frame sent. */
void plem_master_write(struct plem_master *master, const plem_arm *arm, const uint16_t *controlwords);

/* Make a fresh arm ready for its first cycle (settings and model already written). */
void plem_arm_init(plem_arm *arm);
/* One cycle: read the bus (the simulated arm, the EtherCAT master, or process data the caller put in io_*),
 * supervise, take requests, control, check the command against every limit, write the bus, publish. */
void plem_arm_cycle(plem_arm *arm, const plem_bus *bus, const plem_slab *slab, plem_state_block *block,
                    plem_stream_block *stream);
/* Fault from outside the cycle (consecutive overruns, a failing caller), with two numbers for the reason. */
void plem_arm_fault(plem_arm *arm, int cause, double value0, double value1);
/* The summary of one overrun window, as an event. */
void plem_arm_report_overruns(plem_arm *arm, int64_t overruns, int64_t missed, int64_t longest, int64_t total,
                              int64_t window_ms);

/* ---- the real-time thread ------------------------------------------------------------------------------ */

#define PLEM_HISTOGRAM_BINS 10000     /* 1 µs bins: 0..10 ms, the last counts everything above */
#define PLEM_WINDOW 10000             /* the most recent samples, for live figures */

/* One timed quantity of the loop: whole-run histogram and a rolling window of raw samples (ns). */
typedef struct {
    int64_t count, total_ns, min_ns, max_ns;
    int64_t histogram[PLEM_HISTOGRAM_BINS];
    int64_t window[PLEM_WINDOW];
} plem_series;

/* The loop's timing and what it obtained from the machine. */
typedef struct {
    int64_t cycles, overruns, missed_periods, consecutive_overruns;
    int32_t policy;                   /* 1 once the thread runs at SCHED_FIFO */
    int32_t priority;
    int32_t sched_error;              /* errno of the refused scheduling request, 0 when granted */
    int32_t affinity_error;           /* errno of the refused CPU affinity, 0 when granted or not asked */
    uint64_t cpus;                    /* the CPUs the thread may run on */
    plem_series latency, compute;
} plem_stats;

/* A ring of the RT driver's rt_raw records in shared memory (the layout of plem.ipc.ring). */
typedef struct {
    uint8_t *base;
    int64_t slot_bytes, slots;
} plem_raw_ring;

void plem_series_add(plem_series *series, int64_t value_ns);
/* One rt_raw record from the state block the cycle just published, with its timing and the speed override. */
void plem_raw_write(plem_raw_ring *ring, const plem_state_block *block, int dof, int64_t latency_ns,
                    int64_t compute_ns, double speed_override);

#endif
