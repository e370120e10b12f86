/* Rigid-body dynamics of an arm: inverse dynamics (recursive Newton-Euler) and forward dynamics
 * (articulated-body algorithm), in pinocchio's conventions so the results agree with its rnea and aba.
 *
 * Spatial vectors are (linear, angular). A joint's placement maps its frame into its parent's:
 * x_parent = R x_joint + p, with R and p the placement times the joint's own motion at q.
 */
#include <math.h>
#include <string.h>

#include "plem_core.h"

typedef struct { double lin[3], ang[3]; } spatial;
typedef struct { double R[9], p[3]; } placement;

static void cross(const double *a, const double *b, double *out) {
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    out[0] = x, out[1] = y, out[2] = z;
}

static void rotate(const double *R, const double *x, double *out) {
    for (int r = 0; r < 3; r++) out[r] = R[3 * r] * x[0] + R[3 * r + 1] * x[1] + R[3 * r + 2] * x[2];
}

static void rotate_back(const double *R, const double *x, double *out) {
    for (int c = 0; c < 3; c++) out[c] = R[c] * x[0] + R[3 + c] * x[1] + R[6 + c] * x[2];
}

/* The joint's frame in its parent's frame at position q. */
static void joint_placement(const plem_model *m, int k, double q, placement *out) {
    const double *R0 = m->rotation[k], *p0 = m->translation[k], *u = m->axis[k];
    if (m->kind[k] == PLEM_PRISMATIC) {
        memcpy(out->R, R0, sizeof out->R);
        double shift[3] = {u[0] * q, u[1] * q, u[2] * q};
        rotate(R0, shift, out->p);
        for (int i = 0; i < 3; i++) out->p[i] += p0[i];
        return;
    }
    double c = cos(q), s = sin(q), t = 1.0 - c, J[9] = {
        c + t * u[0] * u[0],        t * u[0] * u[1] - s * u[2], t * u[0] * u[2] + s * u[1],
        t * u[0] * u[1] + s * u[2], c + t * u[1] * u[1],        t * u[1] * u[2] - s * u[0],
        t * u[0] * u[2] - s * u[1], t * u[1] * u[2] + s * u[0], c + t * u[2] * u[2]};
    for (int r = 0; r < 3; r++)
        for (int col = 0; col < 3; col++)
            out->R[3 * r + col] = R0[3 * r] * J[col] + R0[3 * r + 1] * J[3 + col] + R0[3 * r + 2] * J[6 + col];
    memcpy(out->p, p0, sizeof out->p);
}

/* A motion of the parent's frame seen in the joint's frame. */
static void motion_into(const placement *X, const spatial *m, spatial *out) {
    double w[3];
    cross(X->p, m->ang, w);
    for (int i = 0; i < 3; i++) w[i] = m->lin[i] - w[i];
    rotate_back(X->R, m->ang, out->ang);
    rotate_back(X->R, w, out->lin);
}

/* A force in the joint's frame seen in the parent's frame, added to `out`. */
static void add_force_out(const placement *X, const spatial *f, spatial *out) {
    double lin[3], ang[3], moment[3];
    rotate(X->R, f->lin, lin);
    rotate(X->R, f->ang, ang);
    cross(X->p, lin, moment);
    for (int i = 0; i < 3; i++) out->lin[i] += lin[i], out->ang[i] += ang[i] + moment[i];
}

/* v × m for motions: (w × m.lin + v.lin × m.ang, w × m.ang). */
static void motion_cross(const spatial *v, const spatial *m, spatial *out) {
    double a[3], b[3];
    cross(v->ang, m->lin, a);
    cross(v->lin, m->ang, b);
    cross(v->ang, m->ang, out->ang);
    for (int i = 0; i < 3; i++) out->lin[i] = a[i] + b[i];
}

/* v ×* f for forces: (w × f.lin, w × f.ang + v.lin × f.lin). */
static void force_cross(const spatial *v, const spatial *f, spatial *out) {
    double a[3], b[3];
    cross(v->ang, f->lin, out->lin);
    cross(v->ang, f->ang, a);
    cross(v->lin, f->lin, b);
    for (int i = 0; i < 3; i++) out->ang[i] = a[i] + b[i];
}

/* The body's spatial inertia applied to a motion. */
static void inertia_times(const plem_model *model, int k, const spatial *m, spatial *out) {
    const double mass = model->mass[k], *c = model->com[k];
    double cw[3], Iw[3], moment[3];
    cross(c, m->ang, cw);
    for (int i = 0; i < 3; i++) out->lin[i] = mass * (m->lin[i] - cw[i]);
    rotate(model->inertia[k], m->ang, Iw);
    cross(c, out->lin, moment);
    for (int i = 0; i < 3; i++) out->ang[i] = Iw[i] + moment[i];
}

/* The joint's motion subspace times a rate: its axis in the linear or angular part. */
static void along_axis(const plem_model *m, int k, double rate, spatial *out) {
    const double *u = m->axis[k];
    int prismatic = m->kind[k] == PLEM_PRISMATIC;
    for (int i = 0; i < 3; i++) {
        out->lin[i] = prismatic ? u[i] * rate : 0.0;
        out->ang[i] = prismatic ? 0.0 : u[i] * rate;
    }
}

/* The part of a force or motion along the joint's axis. */
static double on_axis(const plem_model *m, int k, const spatial *f) {
    const double *u = m->axis[k], *part = m->kind[k] == PLEM_PRISMATIC ? f->lin : f->ang;
    return u[0] * part[0] + u[1] * part[1] + u[2] * part[2];
}

static void base_acceleration(const plem_model *m, spatial *out) {
    for (int i = 0; i < 3; i++) out->lin[i] = -m->gravity[i], out->ang[i] = 0.0;
}

void plem_inverse_dynamics(const plem_model *model, const double *q, const double *v, const double *a, double *tau) {
    int n = model->dof;
    placement X[PLEM_MAX_JOINTS];
    spatial vel[PLEM_MAX_JOINTS], acc[PLEM_MAX_JOINTS], force[PLEM_MAX_JOINTS], base, zero = {{0, 0, 0}, {0, 0, 0}};
    base_acceleration(model, &base);
    for (int k = 0; k < n; k++) {
        int j = model->arm_index[k], parent = model->parent[k];
        spatial joint_velocity, joint_acceleration, coriolis, momentum, bias;
        joint_placement(model, k, q[j], &X[k]);
        motion_into(&X[k], parent < 0 ? &zero : &vel[parent], &vel[k]);
        along_axis(model, k, v[j], &joint_velocity);
        for (int i = 0; i < 3; i++) vel[k].lin[i] += joint_velocity.lin[i], vel[k].ang[i] += joint_velocity.ang[i];
        motion_into(&X[k], parent < 0 ? &base : &acc[parent], &acc[k]);
        along_axis(model, k, a[j], &joint_acceleration);
        motion_cross(&vel[k], &joint_velocity, &coriolis);
        for (int i = 0; i < 3; i++) {
            acc[k].lin[i] += joint_acceleration.lin[i] + coriolis.lin[i];
            acc[k].ang[i] += joint_acceleration.ang[i] + coriolis.ang[i];
        }
        inertia_times(model, k, &acc[k], &force[k]);
        inertia_times(model, k, &vel[k], &momentum);
        force_cross(&vel[k], &momentum, &bias);
        for (int i = 0; i < 3; i++) force[k].lin[i] += bias.lin[i], force[k].ang[i] += bias.ang[i];
    }
    for (int k = n - 1; k >= 0; k--) {
        tau[model->arm_index[k]] = on_axis(model, k, &force[k]);
        if (model->parent[k] >= 0) add_force_out(&X[k], &force[k], &force[model->parent[k]]);
    }
}

void plem_gravity(const plem_model *model, const double *q, double *tau) {
    double zero[PLEM_MAX_JOINTS] = {0};
    plem_inverse_dynamics(model, q, zero, zero, tau);
}

typedef double matrix6[6][6];

/* The body's 6×6 spatial inertia, rows and columns (linear, angular). */
static void spatial_inertia(const plem_model *m, int k, matrix6 out) {
    const double mass = m->mass[k], *c = m->com[k], *I = m->inertia[k];
    double C[3][3] = {{0, -c[2], c[1]}, {c[2], 0, -c[0]}, {-c[1], c[0], 0}};
    memset(out, 0, sizeof(matrix6));
    for (int r = 0; r < 3; r++) {
        out[r][r] = mass;
        for (int col = 0; col < 3; col++) {
            out[r][3 + col] = -mass * C[r][col];
            out[3 + r][col] = mass * C[r][col];
            double cc = 0.0;
            for (int i = 0; i < 3; i++) cc += C[r][i] * C[i][col];
            out[3 + r][3 + col] = I[3 * r + col] - mass * cc;
        }
    }
}

/* out += F A Fᵀ with F = [[R, 0], [[p]× R, R]]: an articulated inertia moved into the parent's frame. */
static void add_inertia_out(const placement *X, matrix6 A, matrix6 out) {
    const double *R = X->R, *p = X->p;
    double P[3][3] = {{0, -p[2], p[1]}, {p[2], 0, -p[0]}, {-p[1], p[0], 0}};
    matrix6 F = {{0}}, FA;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            F[r][c] = F[3 + r][3 + c] = R[3 * r + c];
            double pr = 0.0;
            for (int i = 0; i < 3; i++) pr += P[r][i] * R[3 * i + c];
            F[3 + r][c] = pr;
        }
    for (int r = 0; r < 6; r++)
        for (int c = 0; c < 6; c++) {
            double sum = 0.0;
            for (int i = 0; i < 6; i++) sum += F[r][i] * A[i][c];
            FA[r][c] = sum;
        }
    for (int r = 0; r < 6; r++)
        for (int c = 0; c < 6; c++) {
            double sum = 0.0;
            for (int i = 0; i < 6; i++) sum += FA[r][i] * F[c][i];
            out[r][c] += sum;
        }
}

static void as_array(const spatial *s, double *out) {
    for (int i = 0; i < 3; i++) out[i] = s->lin[i], out[3 + i] = s->ang[i];
}

static void from_array(const double *x, spatial *out) {
    for (int i = 0; i < 3; i++) out->lin[i] = x[i], out->ang[i] = x[3 + i];
}

void plem_forward_dynamics(const plem_model *model, const double *q, const double *v, const double *tau, double *a) {
    int n = model->dof;
    placement X[PLEM_MAX_JOINTS];
    spatial vel[PLEM_MAX_JOINTS], bias_acc[PLEM_MAX_JOINTS], acc[PLEM_MAX_JOINTS], zero = {{0, 0, 0}, {0, 0, 0}}, base;
    matrix6 IA[PLEM_MAX_JOINTS];
    double pA[PLEM_MAX_JOINTS][6], U[PLEM_MAX_JOINTS][6], D[PLEM_MAX_JOINTS], u[PLEM_MAX_JOINTS];
    for (int k = 0; k < n; k++) {
        int j = model->arm_index[k], parent = model->parent[k];
        spatial joint_velocity, momentum, bias;
        joint_placement(model, k, q[j], &X[k]);
        motion_into(&X[k], parent < 0 ? &zero : &vel[parent], &vel[k]);
        along_axis(model, k, v[j], &joint_velocity);
        for (int i = 0; i < 3; i++) vel[k].lin[i] += joint_velocity.lin[i], vel[k].ang[i] += joint_velocity.ang[i];
        motion_cross(&vel[k], &joint_velocity, &bias_acc[k]);
        spatial_inertia(model, k, IA[k]);
        inertia_times(model, k, &vel[k], &momentum);
        force_cross(&vel[k], &momentum, &bias);
        as_array(&bias, pA[k]);
    }
    for (int k = n - 1; k >= 0; k--) {
        int block = model->kind[k] == PLEM_PRISMATIC ? 0 : 3, parent = model->parent[k];
        const double *axis = model->axis[k];
        for (int r = 0; r < 6; r++)
            U[k][r] = IA[k][r][block] * axis[0] + IA[k][r][block + 1] * axis[1] + IA[k][r][block + 2] * axis[2];
        D[k] = U[k][block] * axis[0] + U[k][block + 1] * axis[1] + U[k][block + 2] * axis[2];
        u[k] = tau[model->arm_index[k]]
               - (pA[k][block] * axis[0] + pA[k][block + 1] * axis[1] + pA[k][block + 2] * axis[2]);
        if (parent < 0) continue;
        double c[6], pa[6];
        as_array(&bias_acc[k], c);
        for (int r = 0; r < 6; r++)
            for (int col = 0; col < 6; col++) IA[k][r][col] -= U[k][r] * U[k][col] / D[k];
        for (int r = 0; r < 6; r++) {
            double sum = pA[k][r] + U[k][r] * u[k] / D[k];
            for (int col = 0; col < 6; col++) sum += IA[k][r][col] * c[col];
            pa[r] = sum;
        }
        add_inertia_out(&X[k], IA[k], IA[parent]);
        spatial force, parent_force;
        from_array(pa, &force);
        from_array(pA[parent], &parent_force);
        add_force_out(&X[k], &force, &parent_force);
        as_array(&parent_force, pA[parent]);
    }
    base_acceleration(model, &base);
    for (int k = 0; k < n; k++) {
        int parent = model->parent[k];
        double ak[6];
        motion_into(&X[k], parent < 0 ? &base : &acc[parent], &acc[k]);
        for (int i = 0; i < 3; i++) acc[k].lin[i] += bias_acc[k].lin[i], acc[k].ang[i] += bias_acc[k].ang[i];
        as_array(&acc[k], ak);
        double dot = 0.0;
        for (int r = 0; r < 6; r++) dot += U[k][r] * ak[r];
        double qdd = (u[k] - dot) / D[k];
        a[model->arm_index[k]] = qdd;
        spatial joint_acceleration;
        along_axis(model, k, qdd, &joint_acceleration);
        for (int i = 0; i < 3; i++) {
            acc[k].lin[i] += joint_acceleration.lin[i];
            acc[k].ang[i] += joint_acceleration.ang[i];
        }
    }
}

/* ---- kinematics of a point: Jacobians and wrenches ----------------------------------------------------------- */

/* Every joint frame's placement in the base frame at q (arm order). */
static void world_placements(const plem_model *m, const double *q, placement *W) {
    for (int k = 0; k < m->dof; k++) {
        placement X;
        joint_placement(m, k, q[m->arm_index[k]], &X);
        int parent = m->parent[k];
        if (parent < 0) {
            W[k] = X;
            continue;
        }
        const placement *P = &W[parent];
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                W[k].R[3 * r + c] = P->R[3 * r] * X.R[c] + P->R[3 * r + 1] * X.R[3 + c] + P->R[3 * r + 2] * X.R[6 + c];
        rotate(P->R, X.p, W[k].p);
        for (int i = 0; i < 3; i++) W[k].p[i] += P->p[i];
    }
}

void plem_point_jacobian(const plem_model *model, const double *q, int body, const double *point, double *jacobian) {
    int n = model->dof;
    placement W[PLEM_MAX_JOINTS];
    memset(jacobian, 0, 6 * (size_t)n * sizeof(double));
    if (body < 0 || body >= n) return;
    world_placements(model, q, W);
    double p[3];
    rotate(W[body].R, point, p);
    for (int i = 0; i < 3; i++) p[i] += W[body].p[i];
    for (int k = body; k >= 0; k = model->parent[k]) {   /* the joints that move the body: its ancestors */
        double z[3], lever[3], linear[3];
        rotate(W[k].R, model->axis[k], z);
        int column = model->arm_index[k];
        if (model->kind[k] == PLEM_PRISMATIC) {
            for (int i = 0; i < 3; i++) jacobian[i * n + column] = z[i];
            continue;
        }
        for (int i = 0; i < 3; i++) lever[i] = p[i] - W[k].p[i];
        cross(z, lever, linear);
        for (int i = 0; i < 3; i++) jacobian[i * n + column] = linear[i], jacobian[(3 + i) * n + column] = z[i];
    }
}

void plem_wrench_torques(const plem_model *model, const double *q, int body, const double *point,
                         const double *wrench, double *tau) {
    int n = model->dof;
    double J[6 * PLEM_MAX_JOINTS];
    plem_point_jacobian(model, q, body, point, J);
    for (int c = 0; c < n; c++) {
        tau[c] = 0.0;
        for (int r = 0; r < 6; r++) tau[c] += J[r * n + c] * wrench[r];
    }
}

/* The wrench at the origin of the last joint's frame that best explains joint torques `tau`: the damped least
 * squares (J·Jᵀ + λ²·I)·F = J·τ, solved by Gaussian elimination (6 × 6, symmetric positive definite). */
void plem_tool_wrench(const plem_model *model, const double *q, const double *tau, double *wrench) {
    int n = model->dof;
    double J[6 * PLEM_MAX_JOINTS], A[6][7], origin[3] = {0.0, 0.0, 0.0};
    plem_point_jacobian(model, q, n - 1, origin, J);
    for (int r = 0; r < 6; r++) {
        for (int c = 0; c < 6; c++) {
            double sum = r == c ? 1e-6 : 0.0;
            for (int k = 0; k < n; k++) sum += J[r * n + k] * J[c * n + k];
            A[r][c] = sum;
        }
        double b = 0.0;
        for (int k = 0; k < n; k++) b += J[r * n + k] * tau[k];
        A[r][6] = b;
    }
    for (int c = 0; c < 6; c++)
        for (int r = c + 1; r < 6; r++) {
            double f = A[r][c] / A[c][c];
            for (int k = c; k < 7; k++) A[r][k] -= f * A[c][k];
        }
    for (int c = 5; c >= 0; c--) {
        double x = A[c][6];
        for (int k = c + 1; k < 6; k++) x -= A[c][k] * wrench[k];
        wrench[c] = x / A[c][c];
    }
}
