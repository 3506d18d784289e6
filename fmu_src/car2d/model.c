/* The 2D car of the in-service seed (the Python twin: calibration/models/car2d.py's
 * build_car): carbody, bogie 1 (leading, x = +L_v) and bogie 2, each moving vertically and
 * pitching; secondary spring-dampers between the carbody at x = +-L_v and the bogie
 * centres; primary spring-dampers between each bogie at its wheelsets' positions and the
 * rail level under the wheelset (inputs z_rail_j and their rates dz_rail_j).
 *
 * An extended model (a diagnosis's calibration file, its `extras`) adds, as model_config.h's
 * CAR_* switches say (fmu_src/variables.py sets them from the calibration):
 *   CAR_COG        the carbody's centre of mass cog_offset ahead of its middle;
 *   CAR_BENDING    the carbody's first free-free bending, one more coordinate (modal mass
 *                  bending_mass_ratio m_v, bending_hz, bending_damping), its shape the
 *                  uniform beam's stretched so that its nodes sit at +-bending_node of the
 *                  half-length of a carbody_length body, 1 at the ends;
 *   CAR_RESERVOIR  per air spring a reservoir: reservoir_ratio k_s in series with an orifice
 *                  damper of corner frequency reservoir_corner_hz, the node between them of
 *                  node_mass;
 *   CAR_TRACK      a flexible track: under each wheelset track_mass of rail and sleeper on
 *                  the track's stiffness track_stiffness and damping (track_damping_ratio of
 *                  the track mass's critical damping), z_rail_j the level at the wheel-rail
 *                  contact, the wheelset on the rail. Its coordinate y is the centre of mass of
 *                  wheelset and track mass (m_w + track_mass), the wheelset at y + (1 - a) z_j
 *                  and the track at y - a z_j, a = m_w / (m_w + track_mass): no z_j'' term;
 *   CAR_N_HUNG     point masses hung under the carbody on one spring-damper each
 *                  (CAR_HUNG_VRS: their mass, x, mount stiffness and damping), part of m_v
 *                  when CAR_HUNG_IN_M_V (the rigid carbody keeps the rest).
 *
 * Assembled from that element list the way calibration.models.assembly does it: a point at
 * x on a body moves g q with g = (1, -(x - x_body), shape(x - x_body)) on the body's
 * (z, pitch, bending); an element with elongation e = g_top q - g_bot q + h u adds k g g^T
 * to K and -k g h^T to B_k.
 *
 * Outputs (model_config.h's OUTPUTS table): accelerations of body points, pitch rates, and
 * the vertical wheel-rail force of each wheelset including the static load: the primary's
 * force on the wheelset plus its inertia force,
 *     F_j = -k_p (g_j (q_s + q) - w_j) - c_p (g_j q' - w_j') + m_w (g + w_j''),
 * w_j the wheelset's level (the rail's, z_j, on a rigid track; its coordinate plus (1 - a) z_j
 * on a flexible one; the z_j'' part of w_j'' the slope of dz_j over the step) and q_s the
 * static deflection under gravity. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "linalg.h"
#include "model.h"

#ifndef CAR_COG
#define CAR_COG 0
#endif
#ifndef CAR_BENDING
#define CAR_BENDING 0
#endif
#ifndef CAR_RESERVOIR
#define CAR_RESERVOIR 0
#endif
#ifndef CAR_TRACK
#define CAR_TRACK 0
#endif
#ifndef CAR_N_HUNG
#define CAR_N_HUNG 0
#endif
#ifndef CAR_HUNG_IN_M_V
#define CAR_HUNG_IN_M_V 0
#endif

#define NW 4 /* wheelsets */
/* bodies: carbody, bogie1, bogie2, then reservoir nodes, wheelsets, hung bodies */
#define B_RES 3
#define B_WHEEL (B_RES + 2 * CAR_RESERVOIR)
#define B_HUNG (B_WHEEL + NW * CAR_TRACK)
#define NB (B_HUNG + CAR_N_HUNG)
#define NQ (6 + CAR_BENDING + 2 * CAR_RESERVOIR + NW * CAR_TRACK + CAR_N_HUNG)

#if 2 * NQ != MODEL_NX
#error "model_config.h: MODEL_NX does not match the car's CAR_* switches"
#endif

#if CAR_N_HUNG > 0
static const int HUNG_VR[CAR_N_HUNG][4] = CAR_HUNG_VRS; /* mass, x, mount stiffness, mount damping */
#endif

typedef struct {
    double mass[NB], inertia[NB], x[NB]; /* inertia 0: a point mass (z only) */
    int first[NB];                        /* its first coordinate in q */
    double xw[NW];
    double bend_length, bend_stretch;     /* the carbody's bending shape (CAR_BENDING) */
} Geometry;

#define TWO_PI 6.283185307179586

static int must(const double *r, int vr, int zero_ok, char *msg, size_t n) {
    const double v = r[vr];
    if (!isfinite(v) || v < 0 || (v == 0 && !zero_ok)) {
        snprintf(msg, n, "%s = %g must be %s", REAL_NAME[vr], v, zero_ok ? ">= 0" : "> 0");
        return -1;
    }
    return 0;
}

static int check(const double *r, char *msg, size_t n) {
    static const struct { int vr; int zero_ok; } checks[] = {
        {VR_m_v, 0}, {VR_J_v, 0}, {VR_m_b, 0}, {VR_J_b, 0}, {VR_m_w, 0}, {VR_k_p, 0},
        {VR_c_p, 1}, {VR_k_s, 0}, {VR_c_s, 1}, {VR_L_v, 0}, {VR_L_b, 0},
#if CAR_BENDING
        {VR_bending_hz, 0}, {VR_bending_damping, 1}, {VR_bending_mass_ratio, 0}, {VR_bending_node, 0},
        {VR_carbody_length, 0},
#endif
#if CAR_RESERVOIR
        {VR_reservoir_ratio, 0}, {VR_reservoir_corner_hz, 0}, {VR_node_mass, 0},
#endif
#if CAR_TRACK
        {VR_track_stiffness, 0}, {VR_track_damping_ratio, 1}, {VR_track_mass, 0},
#endif
    };
    for (size_t i = 0; i < sizeof checks / sizeof checks[0]; i++)
        if (must(r, checks[i].vr, checks[i].zero_ok, msg, n) != 0) return -1;
#if CAR_N_HUNG > 0
    for (int h = 0; h < CAR_N_HUNG; h++) {
        if (must(r, HUNG_VR[h][0], 0, msg, n) || must(r, HUNG_VR[h][2], 0, msg, n) ||
            must(r, HUNG_VR[h][3], 1, msg, n))
            return -1;
        if (!isfinite(r[HUNG_VR[h][1]])) {
            snprintf(msg, n, "%s = %g must be finite", REAL_NAME[HUNG_VR[h][1]], r[HUNG_VR[h][1]]);
            return -1;
        }
    }
#endif
#if CAR_COG
    if (!isfinite(r[VR_cog_offset])) {
        snprintf(msg, n, "cog_offset = %g must be finite", r[VR_cog_offset]);
        return -1;
    }
#endif
    if (!(r[VR_L_b] < r[VR_L_v])) {
        snprintf(msg, n, "half wheelbase L_b = %g m must be smaller than half the bogie spacing L_v = %g m",
                 r[VR_L_b], r[VR_L_v]);
        return -1;
    }
    return 0;
}

/* The rigid carbody: m_v at cog_offset with J_v, less the hung bodies when they are part
 * of m_v (calibration.models.car2d._carbody_rest). */
static int carbody_rest(const double *r, double *m, double *x, double *J, char *msg, size_t n) {
#if CAR_COG
    const double cog = r[VR_cog_offset];
#else
    const double cog = 0.0;
#endif
    *m = r[VR_m_v], *x = cog, *J = r[VR_J_v];
#if CAR_N_HUNG > 0 && CAR_HUNG_IN_M_V
    double m_e = 0.0, mx = 0.0, mxx = 0.0;
    for (int h = 0; h < CAR_N_HUNG; h++) {
        const double me = r[HUNG_VR[h][0]], xe = r[HUNG_VR[h][1]];
        m_e += me, mx += me * xe, mxx += me * xe * xe;
    }
    *m = r[VR_m_v] - m_e;
    *x = *m > 0 ? (r[VR_m_v] * cog - mx) / *m : 0.0;
    *J = r[VR_J_v] + r[VR_m_v] * cog * cog - mxx - *m * *x * *x;
    if (!(*m > 0 && *J > 0)) {
        snprintf(msg, n, "hung bodies of %.0f kg (part of m_v = %.0f kg) leave the carbody %.0f kg and J %.3g kg m^2: "
                 "they must leave it a positive mass and inertia", m_e, r[VR_m_v], *m, *J);
        return -1;
    }
#else
    (void)msg, (void)n;
#endif
    return 0;
}

static int geometry(const double *r, Geometry *g, char *msg, size_t n) {
    const double Lv = r[VR_L_v], Lb = r[VR_L_b];
    if (carbody_rest(r, &g->mass[0], &g->x[0], &g->inertia[0], msg, n) != 0) return -1;
    for (int i = 1; i < 3; i++) g->mass[i] = r[VR_m_b], g->inertia[i] = r[VR_J_b];
    g->x[1] = Lv, g->x[2] = -Lv;
    g->xw[0] = Lv + Lb, g->xw[1] = Lv - Lb, g->xw[2] = -Lv + Lb, g->xw[3] = -Lv - Lb;
#if CAR_RESERVOIR
    for (int i = 0; i < 2; i++)
        g->mass[B_RES + i] = r[VR_node_mass], g->inertia[B_RES + i] = 0.0, g->x[B_RES + i] = g->x[1 + i];
#endif
#if CAR_TRACK
    for (int j = 0; j < NW; j++)
        g->mass[B_WHEEL + j] = r[VR_m_w] + r[VR_track_mass], g->inertia[B_WHEEL + j] = 0.0,
        g->x[B_WHEEL + j] = g->xw[j];
#endif
#if CAR_N_HUNG > 0
    for (int h = 0; h < CAR_N_HUNG; h++)
        g->mass[B_HUNG + h] = r[HUNG_VR[h][0]], g->inertia[B_HUNG + h] = 0.0, g->x[B_HUNG + h] = r[HUNG_VR[h][1]];
#endif
    int q = 0;
    for (int b = 0; b < NB; b++) {
        g->first[b] = q;
        q += g->inertia[b] > 0 ? 2 : 1;
        if (b == 0) q += CAR_BENDING;
    }
#if CAR_BENDING
    g->bend_length = r[VR_carbody_length];
    /* the uniform beam's nodes, as a fraction of the half-length (assembly.UNIFORM_BEAM_NODE) */
    g->bend_stretch = 0.5516849545952847 / r[VR_bending_node];
#else
    g->bend_length = g->bend_stretch = 1.0;
#endif
    return 0;
}

/* First free-free bending of a uniform beam (beta L = 4.7300), stretched, 1 at the ends
 * (calibration.models.assembly.beam_bending_shape). */
static double bending_shape(const Geometry *g, double u) {
    const double bl = 4.730040744862704;
    const double s = (cosh(bl) - cos(bl)) / (sinh(bl) - sin(bl));
    const double b = bl * (g->bend_stretch * u / g->bend_length + 0.5);
    const double e = bl * (g->bend_stretch * 0.5 + 0.5);
    return (cosh(b) + cos(b) - s * (sinh(b) + sin(b))) / (cosh(e) + cos(e) - s * (sinh(e) + sin(e)));
}

/* g: displacement row of the point at x on body b */
static void point_row(const Geometry *geo, int b, double x, double *g) {
    memset(g, 0, NQ * sizeof(double));
    const int f = geo->first[b];
    g[f] = 1.0;
    if (geo->inertia[b] > 0) g[f + 1] = -(x - geo->x[b]);
    if (CAR_BENDING && b == 0) g[f + 2] = bending_shape(geo, x - geo->x[b]);
}

/* spring-damper between body point (bt, xt) and body point (bb, xb) (or ground, bb < 0) plus
 * `gain` x rail input `input` (none: input < 0) */
static void add_element(double *K, double *Cd, double *Bk, double *Bc, const Geometry *geo, int bt, double xt, int bb,
                        double xb, int input, double gain, double k, double c) {
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
        for (int i = 0; i < NQ; i++) { /* h = -gain e_input (the rail is at the bottom attachment) */
            Bk[i * NW + input] += gain * k * g[i];
            Bc[i * NW + input] += gain * c * g[i];
        }
}

/* The wheelset j's body (free wheelsets), or -1 on the rail. */
static int wheel_body(int j) { return CAR_TRACK ? B_WHEEL + j : -1; }

/* On a flexible track: m_t / (m_w + m_t), the share of its rail level a wheelset rides above
 * its coordinate (calibration.models.car2d.wheel_level_gain); 1 on the rail (no coordinate). */
static double wheel_gain(const double *r) {
#if CAR_TRACK
    return r[VR_track_mass] / (r[VR_m_w] + r[VR_track_mass]);
#else
    (void)r;
    return 1.0;
#endif
}

int model_build(const double *r, LtiSystem *sys, char *msg, size_t msg_len) {
    for (int j = 0; j < NW; j++)
        if (INPUT_VR[j] != VR_z_rail_1 + j || INPUT_VR[NW + j] != VR_dz_rail_1 + j) {
            snprintf(msg, msg_len, "model_config.h: inputs must be z_rail_1..4 then dz_rail_1..4");
            return -1;
        }
    if (check(r, msg, msg_len) != 0) return -1;
    Geometry geo;
    if (geometry(r, &geo, msg, msg_len) != 0) return -1;
    double K[NQ * NQ] = {0}, Cd[NQ * NQ] = {0}, Bk[NQ * NW] = {0}, Bc[NQ * NW] = {0}, mass[NQ * NQ] = {0};
    for (int b = 0; b < NB; b++) {
        const int f = geo.first[b];
        mass[f * NQ + f] = geo.mass[b];
        if (geo.inertia[b] > 0) mass[(f + 1) * NQ + f + 1] = geo.inertia[b];
    }
#if CAR_BENDING
    {   /* the bending coordinate's modal mass, stiffness and damping */
        const int i = geo.first[0] + 2;
        const double mm = r[VR_bending_mass_ratio] * r[VR_m_v], w = TWO_PI * r[VR_bending_hz];
        mass[i * NQ + i] = mm;
        K[i * NQ + i] = mm * w * w;
        Cd[i * NQ + i] = 2 * r[VR_bending_damping] * mm * w;
    }
#endif
    for (int i = 0; i < 2; i++)
        add_element(K, Cd, Bk, Bc, &geo, 0, geo.x[1 + i], 1 + i, geo.x[1 + i], -1, 0.0, r[VR_k_s], r[VR_c_s]);
#if CAR_RESERVOIR
    for (int i = 0; i < 2; i++) {
        const double k_r = r[VR_reservoir_ratio] * r[VR_k_s], c_o = k_r / (TWO_PI * r[VR_reservoir_corner_hz]);
        add_element(K, Cd, Bk, Bc, &geo, 0, geo.x[1 + i], B_RES + i, geo.x[1 + i], -1, 0.0, k_r, 0.0);
        add_element(K, Cd, Bk, Bc, &geo, B_RES + i, geo.x[1 + i], 1 + i, geo.x[1 + i], -1, 0.0, 0.0, c_o);
    }
#endif
    const double above = wheel_gain(r); /* the wheelset rides this x its rail level above its coordinate */
    for (int j = 0; j < NW; j++) {
        const int w = wheel_body(j);
#if CAR_TRACK
        const double k = r[VR_track_stiffness], m_t = r[VR_track_mass];
        add_element(K, Cd, Bk, Bc, &geo, w, geo.xw[j], -1, 0.0, j, 1.0 - above, k,
                    2 * r[VR_track_damping_ratio] * sqrt(k * m_t));
        add_element(K, Cd, Bk, Bc, &geo, 1 + j / 2, geo.xw[j], w, geo.xw[j], j, above, r[VR_k_p], r[VR_c_p]);
#else
        add_element(K, Cd, Bk, Bc, &geo, 1 + j / 2, geo.xw[j], -1, 0.0, j, 1.0, r[VR_k_p], r[VR_c_p]);
#endif
    }
#if CAR_N_HUNG > 0
    for (int h = 0; h < CAR_N_HUNG; h++)
        add_element(K, Cd, Bk, Bc, &geo, 0, geo.x[B_HUNG + h], B_HUNG + h, geo.x[B_HUNG + h], -1, 0.0, r[HUNG_VR[h][2]],
                    r[HUNG_VR[h][3]]);
#endif
    double minv[NQ];
    for (int i = 0; i < NQ; i++) minv[i] = 1.0 / mass[i * NQ + i];
    /* q'' = ax x + aw u with x = (q, q'), u = (z_1..4, dz_1..4) */
    static const int nx2 = 2 * NQ;
    double ax[NQ * 2 * NQ], aw[NQ * 2 * NW];
    for (int i = 0; i < NQ; i++) {
        for (int j = 0; j < NQ; j++) {
            ax[i * nx2 + j] = -minv[i] * K[i * NQ + j];
            ax[i * nx2 + NQ + j] = -minv[i] * Cd[i * NQ + j];
        }
        for (int j = 0; j < NW; j++) {
            aw[i * 2 * NW + j] = minv[i] * Bk[i * NW + j];
            aw[i * 2 * NW + NW + j] = minv[i] * Bc[i * NW + j];
        }
    }
    memset(sys, 0, sizeof *sys);
    for (int i = 0; i < NQ; i++) {
        sys->A[i * MODEL_NX + NQ + i] = 1.0;
        for (int j = 0; j < nx2; j++) sys->A[(NQ + i) * MODEL_NX + j] = ax[i * nx2 + j];
        for (int j = 0; j < 2 * NW; j++) sys->B[(NQ + i) * MODEL_NU + j] = aw[i * 2 * NW + j];
    }
    /* static deflection under gravity: K q_s = f, f = -m g on the vertical DOFs */
    double Kf[NQ * NQ], qs[NQ] = {0};
    int piv[NQ];
    memcpy(Kf, K, sizeof Kf);
    for (int b = 0; b < NB; b++) qs[geo.first[b]] = -geo.mass[b] * MODEL_GRAVITY;
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
                for (int j = 0; j < nx2; j++) Crow[j] += g[i] * ax[i * nx2 + j];
                for (int j = 0; j < 2 * NW; j++) Drow[j] += g[i] * aw[i * 2 * NW + j];
            }
            break;
        case OUT_PITCH_RATE:
            Crow[NQ + geo.first[s->body] + 1] = 1.0;
            break;
        case OUT_CONTACT: {
            const int j = s->wheel, w = wheel_body(j);
            double gw[NQ];
            point_row(&geo, 1 + j / 2, geo.xw[j], g);
            if (w >= 0) {
                point_row(&geo, w, geo.xw[j], gw);
                for (int i = 0; i < NQ; i++) g[i] -= gw[i];
            }
            double static_primary = 0.0;
            for (int i = 0; i < NQ; i++) {
                Crow[i] = -r[VR_k_p] * g[i];
                Crow[NQ + i] = -r[VR_c_p] * g[i];
                static_primary -= r[VR_k_p] * g[i] * qs[i];
            }
            if (w >= 0) { /* the coordinate's acceleration */
                const int f = geo.first[w];
                for (int i = 0; i < nx2; i++) Crow[i] += r[VR_m_w] * ax[f * nx2 + i];
                for (int i = 0; i < 2 * NW; i++) Drow[i] += r[VR_m_w] * aw[f * 2 * NW + i];
            }
            /* the share of the rail level the wheelset rides (all of it on the rail) */
            Drow[j] += above * r[VR_k_p];
            Drow[NW + j] += above * r[VR_c_p];
            Dsrow[NW + j] += above * r[VR_m_w];
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
    const double Lv = r[VR_L_v], Lb = r[VR_L_b];
    const double xw[NW] = {Lv + Lb, Lv - Lb, -Lv + Lb, -Lv - Lb};
    for (int j = 0; j < MODEL_NU; j++) rail->kind[j] = MODEL_RAIL_NONE, rail->offset[j] = 0.0;
    for (int j = 0; j < NW; j++) {
        rail->kind[j] = 0, rail->offset[j] = xw[j];
        rail->kind[NW + j] = 1, rail->offset[NW + j] = xw[j];
    }
}
