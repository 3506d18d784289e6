/* The 2D car of the in-service seed (the Python twin: calibration/models/car2d.py with
 * wheelsets on the rail): carbody, bogie 1 (leading, x = +L_v) and bogie 2, each moving
 * vertically and pitching; secondary spring-dampers between the carbody at x = +-L_v and the
 * bogie centres; primary spring-dampers between each bogie at its wheelsets' positions and
 * the rail level under the wheelset (inputs z_rail_j and their rates dz_rail_j).
 *
 * Assembled from that element list the way calibration.models.assembly does it: a point at
 * x on a body moves g q with g = (1, -(x - x_body)) on the body's (z, pitch); an element
 * with elongation e = g_top q - g_bot q + h u adds k g g^T to K and -k g h^T to B_k.
 *
 * Outputs (model_config.h's OUTPUTS table): accelerations of body points, pitch rates, and
 * the vertical wheel-rail force of each wheelset including the static load,
 *     F_j = -k_p (g_j (q_s + q) - z_j) - c_p (g_j q' - dz_j) + m_w (g + ddz_j),
 * with q_s the static deflection under gravity and ddz_j the slope of dz_j over the step. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "linalg.h"
#include "model.h"

#define NB 3      /* bodies: carbody, bogie1, bogie2 */
#define NQ (2 * NB)
#define NW 4      /* wheelsets */

typedef struct {
    double mass[NB], inertia[NB], x[NB];
    double xw[NW];
} Geometry;

static int check(const double *r, char *msg, size_t n) {
    static const struct { int vr; int zero_ok; } checks[] = {
        {VR_m_v, 0}, {VR_J_v, 0}, {VR_m_b, 0}, {VR_J_b, 0}, {VR_m_w, 0}, {VR_k_p, 0},
        {VR_c_p, 1}, {VR_k_s, 0}, {VR_c_s, 1}, {VR_L_v, 0}, {VR_L_b, 0}};
    for (size_t i = 0; i < sizeof checks / sizeof checks[0]; i++) {
        const double v = r[checks[i].vr];
        if (!isfinite(v) || v < 0 || (v == 0 && !checks[i].zero_ok)) {
            snprintf(msg, n, "%s = %g must be %s", REAL_NAME[checks[i].vr], v, checks[i].zero_ok ? ">= 0" : "> 0");
            return -1;
        }
    }
    if (!(r[VR_L_b] < r[VR_L_v])) {
        snprintf(msg, n, "half wheelbase L_b = %g m must be smaller than half the bogie spacing L_v = %g m",
                 r[VR_L_b], r[VR_L_v]);
        return -1;
    }
    return 0;
}

static void geometry(const double *r, Geometry *g) {
    const double Lv = r[VR_L_v], Lb = r[VR_L_b];
    g->mass[0] = r[VR_m_v], g->inertia[0] = r[VR_J_v], g->x[0] = 0.0;
    for (int i = 1; i < NB; i++) g->mass[i] = r[VR_m_b], g->inertia[i] = r[VR_J_b];
    g->x[1] = Lv, g->x[2] = -Lv;
    g->xw[0] = Lv + Lb, g->xw[1] = Lv - Lb, g->xw[2] = -Lv + Lb, g->xw[3] = -Lv - Lb;
}

/* g: displacement row of the point at x on body b */
static void point_row(const Geometry *geo, int b, double x, double *g) {
    memset(g, 0, NQ * sizeof(double));
    g[2 * b] = 1.0;
    g[2 * b + 1] = -(x - geo->x[b]);
}

/* spring-damper between body point (bt, xt) and body point (bb, xb) or rail input `input` */
static void add_element(double *K, double *Cd, double *Bk, double *Bc, const Geometry *geo, int bt, double xt, int bb,
                        double xb, int input, double k, double c) {
    double g[NQ], gb[NQ];
    point_row(geo, bt, xt, g);
    if (bb >= 0) {
        point_row(geo, bb, xb, gb);
        for (int i = 0; i < NQ; i++) g[i] -= gb[i];
    }
    for (int i = 0; i < NQ; i++)
        for (int j = 0; j < NQ; j++) {
            K[i * NQ + j] += k * g[i] * g[j];
            Cd[i * NQ + j] += c * g[i] * g[j];
        }
    if (input >= 0)
        for (int i = 0; i < NQ; i++) { /* h = -e_input (the rail is the bottom attachment) */
            Bk[i * NW + input] += k * g[i];
            Bc[i * NW + input] += c * g[i];
        }
}

int model_build(const double *r, LtiSystem *sys, char *msg, size_t msg_len) {
    for (int j = 0; j < NW; j++)
        if (INPUT_VR[j] != VR_z_rail_1 + j || INPUT_VR[NW + j] != VR_dz_rail_1 + j) {
            snprintf(msg, msg_len, "model_config.h: inputs must be z_rail_1..4 then dz_rail_1..4");
            return -1;
        }
    if (check(r, msg, msg_len) != 0) return -1;
    Geometry geo;
    geometry(r, &geo);
    double K[NQ * NQ] = {0}, Cd[NQ * NQ] = {0}, Bk[NQ * NW] = {0}, Bc[NQ * NW] = {0};
    for (int i = 0; i < 2; i++)
        add_element(K, Cd, Bk, Bc, &geo, 0, geo.x[1 + i], 1 + i, geo.x[1 + i], -1, r[VR_k_s], r[VR_c_s]);
    for (int j = 0; j < NW; j++)
        add_element(K, Cd, Bk, Bc, &geo, 1 + j / 2, geo.xw[j], -1, 0.0, j, r[VR_k_p], r[VR_c_p]);
    double minv[NQ];
    for (int b = 0; b < NB; b++) minv[2 * b] = 1.0 / geo.mass[b], minv[2 * b + 1] = 1.0 / geo.inertia[b];
    /* q'' = ax x + aw u with x = (q, q'), u = (z_1..4, dz_1..4) */
    double ax[NQ * 2 * NQ], aw[NQ * 2 * NW];
    for (int i = 0; i < NQ; i++) {
        for (int j = 0; j < NQ; j++) {
            ax[i * 2 * NQ + j] = -minv[i] * K[i * NQ + j];
            ax[i * 2 * NQ + NQ + j] = -minv[i] * Cd[i * NQ + j];
        }
        for (int j = 0; j < NW; j++) {
            aw[i * 2 * NW + j] = minv[i] * Bk[i * NW + j];
            aw[i * 2 * NW + NW + j] = minv[i] * Bc[i * NW + j];
        }
    }
    memset(sys, 0, sizeof *sys);
    for (int i = 0; i < NQ; i++) {
        sys->A[i * MODEL_NX + NQ + i] = 1.0;
        for (int j = 0; j < 2 * NQ; j++) sys->A[(NQ + i) * MODEL_NX + j] = ax[i * 2 * NQ + j];
        for (int j = 0; j < 2 * NW; j++) sys->B[(NQ + i) * MODEL_NU + j] = aw[i * 2 * NW + j];
    }
    /* static deflection under gravity: K q_s = f, f = -m g on the vertical DOFs */
    double Kf[NQ * NQ], qs[NQ] = {0};
    int piv[NQ];
    memcpy(Kf, K, sizeof Kf);
    for (int b = 0; b < NB; b++) qs[2 * b] = -geo.mass[b] * MODEL_GRAVITY;
    if (la_lu(NQ, Kf, piv) != 0) {
        snprintf(msg, msg_len, "the suspension stiffness matrix is singular");
        return -1;
    }
    la_lu_solve(NQ, 1, Kf, piv, qs);
    for (int o = 0; o < MODEL_NY; o++) {
        const OutputSpec *s = &OUTPUTS[o];
        double g[NQ];
        double *Crow = sys->C + o * MODEL_NX, *Drow = sys->D + o * MODEL_NU, *Dsrow = sys->Ds + o * MODEL_NU;
        switch (s->kind) {
        case OUT_ACC:
            point_row(&geo, s->body, geo.x[s->body] + s->dx, g);
            for (int i = 0; i < NQ; i++) {
                for (int j = 0; j < 2 * NQ; j++) Crow[j] += g[i] * ax[i * 2 * NQ + j];
                for (int j = 0; j < 2 * NW; j++) Drow[j] += g[i] * aw[i * 2 * NW + j];
            }
            break;
        case OUT_PITCH_RATE:
            Crow[NQ + 2 * s->body + 1] = 1.0;
            break;
        case OUT_CONTACT: {
            const int j = s->wheel;
            point_row(&geo, 1 + j / 2, geo.xw[j], g);
            double static_primary = 0.0;
            for (int i = 0; i < NQ; i++) {
                Crow[i] = -r[VR_k_p] * g[i];
                Crow[NQ + i] = -r[VR_c_p] * g[i];
                static_primary -= r[VR_k_p] * g[i] * qs[i];
            }
            Drow[j] = r[VR_k_p];
            Drow[NW + j] = r[VR_c_p];
            Dsrow[NW + j] = r[VR_m_w];
            sys->y0[o] = static_primary + r[VR_m_w] * MODEL_GRAVITY;
            break;
        }
        default:
            snprintf(msg, msg_len, "output %s has an unknown kind %d", REAL_NAME[s->vr], s->kind);
            return -1;
        }
    }
    return 0;
}

void model_rail_inputs(const double *r, RailInputs *rail) {
    Geometry geo;
    geometry(r, &geo);
    for (int j = 0; j < MODEL_NU; j++) rail->kind[j] = MODEL_RAIL_NONE, rail->offset[j] = 0.0;
    for (int j = 0; j < NW; j++) {
        rail->kind[j] = 0, rail->offset[j] = geo.xw[j];
        rail->kind[NW + j] = 1, rail->offset[NW + j] = geo.xw[j];
    }
}
