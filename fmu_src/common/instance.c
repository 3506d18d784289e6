#include "instance.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

#include <stdatomic.h>

#define SNAPSHOT_MAGIC 0x7261696cu /* "rail" */
#define VR_BOOL_BASE N_REALS
#define VR_STRING_BASE (N_REALS + N_BOOLS)
#define N_VARIABLES (N_REALS + N_BOOLS + N_STRINGS)
#define MAX_SUBSTEPS 100000

static const char *state_name(InstanceState s) {
    switch (s) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INITIALIZATION: return "initialization mode";
    case ST_STEP: return "step mode";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    }
    return "unknown";
}

int inst_error(Instance *inst, int enter_error_state, const char *fmt, ...) {
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (enter_error_state) inst->s.state = ST_ERROR;
    if (inst->log) inst->log(inst, STATUS_ERROR, "logStatusError", msg);
    return STATUS_ERROR;
}

static void inst_info(Instance *inst, const char *fmt, ...) {
    if (!inst->logging_on || !inst->log) return;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    inst->log(inst, STATUS_OK, "logEvents", msg);
}

int inst_allowed(Instance *inst, const char *function, int states) {
    if (inst->s.state & states) return 1;
    inst_error(inst, 0, "%s is not allowed in state %s", function, state_name(inst->s.state));
    return 0;
}

static void set_defaults(Instance *inst) {
    memset(&inst->s, 0, sizeof inst->s);
    inst->s.magic = SNAPSHOT_MAGIC;
    inst->s.state = ST_INSTANTIATED;
    for (int i = 0; i < N_REALS; i++) inst->s.r[i] = REAL_START[i];
    for (int i = 0; i < N_BOOLS; i++) inst->s.b[i] = BOOL_START[i];
    for (int i = 0; i < N_STRINGS; i++) {
        free(inst->strings[i]);
        inst->strings[i] = NULL;
        const char *v = STRING_START[i] ? STRING_START[i] : "";
        inst->strings[i] = malloc(strlen(v) + 1);
        if (inst->strings[i]) strcpy(inst->strings[i], v);
    }
    inst->dirty = 1;
    for (int k = 0; k < CACHE_SIZE; k++) inst->cache[k].h = 0.0;
    if (inst->track_loaded) track_free(&inst->track);
    inst->track_loaded = 0;
}

Instance *inst_new(const char *name, const char *resource_dir, int fmi_version, LogFunction log, void *env,
                   int logging_on) {
    Instance *inst = calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    snprintf(inst->name, sizeof inst->name, "%s", name ? name : "");
    snprintf(inst->resource_dir, sizeof inst->resource_dir, "%s", resource_dir ? resource_dir : "");
    inst->fmi_version = fmi_version;
    inst->log = log;
    inst->env = env;
    inst->logging_on = logging_on;
    set_defaults(inst);
    for (int i = 0; i < N_STRINGS; i++)
        if (!inst->strings[i]) {
            inst_free(inst);
            return NULL;
        }
    return inst;
}

void inst_free(Instance *inst) {
    if (!inst) return;
    for (int i = 0; i < N_STRINGS; i++) free(inst->strings[i]);
    if (inst->track_loaded) track_free(&inst->track);
    free(inst);
}

int inst_reset(Instance *inst) {
    set_defaults(inst);
    return STATUS_OK;
}

int inst_enter_init(Instance *inst, double start_time) {
    if (!inst_allowed(inst, "enterInitializationMode", ST_INSTANTIATED)) return STATUS_ERROR;
    if (!isfinite(start_time)) return inst_error(inst, 0, "start time %g is not finite", start_time);
    inst->s.time = start_time;
    inst->s.r[VR_time] = start_time;
    inst->s.state = ST_INITIALIZATION;
    return STATUS_OK;
}

/* ------------------------------------------------------------------ the linear system */

static int rebuild(Instance *inst, int enter_error_state) {
    char msg[512] = "";
    if (model_build(inst->s.r, &inst->sys, msg, sizeof msg) != 0)
        return inst_error(inst, enter_error_state, "invalid parameters: %s", msg);
    for (int k = 0; k < CACHE_SIZE; k++) inst->cache[k].h = 0.0;
    inst->dirty = 0;
    return STATUS_OK;
}

static const Discretisation *discretise(Instance *inst, double h) {
    Discretisation *slot = &inst->cache[0];
    for (int k = 0; k < CACHE_SIZE; k++) {
        Discretisation *c = &inst->cache[k];
        if (c->h > 0.0 && fabs(c->h - h) <= 1e-12 * h) { /* masters' step sizes jitter in the last bits */
            c->used = ++inst->clock;
            return c;
        }
        if (c->used < slot->used) slot = c;
    }
    const int nx = MODEL_NX, nu = MODEL_NU, na = MODEL_NA;
    /* d/dt (x, u, s, c) = (A x + B u, s, c, 0): the inputs follow u + s t + c t^2 / 2 */
    double *M = inst->aug;
    memset(M, 0, sizeof inst->aug);
    for (int i = 0; i < nx; i++) {
        for (int j = 0; j < nx; j++) M[i * na + j] = inst->sys.A[i * nx + j] * h;
        for (int j = 0; j < nu; j++) M[i * na + nx + j] = inst->sys.B[i * nu + j] * h;
    }
    for (int j = 0; j < nu; j++) {
        M[(nx + j) * na + nx + nu + j] = h;
        M[(nx + nu + j) * na + nx + 2 * nu + j] = h;
    }
    if (la_expm(na, M, inst->expA, inst->work, inst->piv) != 0) return NULL;
    for (int i = 0; i < nx; i++) {
        for (int j = 0; j < nx; j++) slot->Phi[i * nx + j] = inst->expA[i * na + j];
        for (int j = 0; j < nu; j++) {
            slot->G0[i * nu + j] = inst->expA[i * na + nx + j];
            slot->G1[i * nu + j] = inst->expA[i * na + nx + nu + j];
            slot->G2[i * nu + j] = inst->expA[i * na + nx + 2 * nu + j];
        }
    }
    slot->h = h;
    slot->used = ++inst->clock;
    return slot;
}

static void outputs(Instance *inst, const double *u, const double *s) {
    const LtiSystem *sys = &inst->sys;
    for (int i = 0; i < MODEL_NY; i++) {
        double y = sys->y0[i];
        for (int j = 0; j < MODEL_NX; j++) y += sys->C[i * MODEL_NX + j] * inst->s.x[j];
        for (int j = 0; j < MODEL_NU; j++) y += sys->D[i * MODEL_NU + j] * u[j] + sys->Ds[i * MODEL_NU + j] * s[j];
        inst->s.r[OUTPUT_VR[i]] = y;
    }
}

/* Inputs over the step from the communication point: u + s t + c t^2 / 2.
 * A level input whose rate is another input takes that rate as its slope and the rate's
 * slope as its curvature, so the pair stays consistent. Any other input's slope is the
 * derivative the master gave (FMI 2 input derivatives, order 1; order 2 gives c) or else
 * the change since the last communication point (linear extrapolation; hold on the first
 * step). */
static void inputs(Instance *inst, double *u, double *s, double *c) {
    for (int j = 0; j < MODEL_NU; j++) {
        u[j] = inst->s.r[INPUT_VR[j]];
        c[j] = inst->s.du2_set[j] ? inst->s.du2[j] : 0.0;
        if (inst->s.du_set[j])
            s[j] = inst->s.du[j];
        else if (inst->s.h_prev > 0.0)
            s[j] = (u[j] - inst->s.u_prev[j]) / inst->s.h_prev;
        else
            s[j] = 0.0;
    }
    for (int j = 0; j < MODEL_NU; j++) {
        const int k = INPUT_RATE_INDEX[j];
        if (k >= 0) {
            s[j] = u[k];
            c[j] = s[k];
        }
    }
}

#if HAS_STANDALONE
/* Inputs from the track at vehicle position `position` and speed v: a rail level z(x)
 * becomes u = z, s = v dz/dx, c = v^2 d2z/dx2; its rate u = v dz/dx, s = v^2 d2z/dx2,
 * c = v^3 d3z/dx3. Inputs that are not rail inputs take their set value and the given
 * derivative (or hold). */
static int track_inputs(Instance *inst, const RailInputs *rail, double position, double v, double *u, double *s,
                        double *c) {
    for (int j = 0; j < MODEL_NU; j++) {
        if (rail->kind[j] == MODEL_RAIL_NONE) {
            u[j] = inst->s.r[INPUT_VR[j]];
            s[j] = inst->s.du_set[j] ? inst->s.du[j] : 0.0;
            c[j] = 0.0;
            continue;
        }
        double d[4];
        const double at = position + rail->offset[j];
        if (!inst->track_loaded) return inst_error(inst, 1, "stand-alone: no track profile is loaded");
        if (track_eval(&inst->track, at, d, &inst->track_hint[j]) != 0)
            return inst_error(inst, 1, "stand-alone: the vehicle runs off the track profile: with the carbody "
                              "centre at %.3f m, input %s needs the track at %.3f m, outside the profile "
                              "%.3f-%.3f m (set track_start, speed or the stop time to stay on it)", position,
                              REAL_NAME[INPUT_VR[j]], at, inst->track.x[0], inst->track.x[inst->track.n - 1]);
        const double *e = d + (rail->kind[j] == 0 ? 0 : 1);
        const double vv = rail->kind[j] == 0 ? 1.0 : v;
        u[j] = vv * e[0];
        s[j] = vv * v * e[1];
        c[j] = vv * v * v * e[2];
    }
    return STATUS_OK;
}

static int load_track(Instance *inst) {
    const char *file = inst->strings[VR_track_file - VR_STRING_BASE];
    if (!file || !*file) return inst_error(inst, 1, "stand-alone running needs a track_file");
    char path[8192], msg[1024];
    if (file[0] == '/' || (file[0] && file[1] == ':') || !inst->resource_dir[0])
        snprintf(path, sizeof path, "%s", file);
    else
        snprintf(path, sizeof path, "%s/%s", inst->resource_dir, file);
    if (inst->track_loaded) track_free(&inst->track);
    inst->track_loaded = 0;
    if (track_load(&inst->track, path, msg, sizeof msg) != 0) return inst_error(inst, 1, "%s", msg);
    inst->track_loaded = 1;
    inst_info(inst, "track profile %s: %d points over %.1f-%.1f m", path, inst->track.n, inst->track.x[0],
              inst->track.x[inst->track.n - 1]);
    return STATUS_OK;
}
#endif

static int check_inputs(Instance *inst) {
    for (int j = 0; j < MODEL_NU; j++)
        if (!isfinite(inst->s.r[INPUT_VR[j]]) || !isfinite(inst->s.du[j]) || !isfinite(inst->s.du2[j]))
            return inst_error(inst, 1, "input %s is not finite", REAL_NAME[INPUT_VR[j]]);
    return STATUS_OK;
}

/* Outputs with direct feedthrough follow inputs set after a step (or parameters changed):
 * recomputed from the state and the inputs as they stand, before they are read. */
static int refresh_outputs(Instance *inst) {
    inst->s.outputs_stale = 0;
    if (inst->dirty && rebuild(inst, 0) != STATUS_OK) return STATUS_ERROR;
    for (int j = 0; j < MODEL_NU; j++)
        if (!isfinite(inst->s.r[INPUT_VR[j]])) return STATUS_OK; /* refused on setting; nothing to show */
    double u[MODEL_NU], s[MODEL_NU], c[MODEL_NU];
#if HAS_STANDALONE
    if (inst->s.b[VR_standalone - VR_BOOL_BASE]) {
        RailInputs rail;
        model_rail_inputs(inst->s.r, &rail);
        if (track_inputs(inst, &rail, inst->s.position, inst->s.r[VR_speed], u, s, c) != STATUS_OK)
            return STATUS_ERROR;
        outputs(inst, u, s);
        return STATUS_OK;
    }
#endif
    inputs(inst, u, s, c);
    outputs(inst, u, s);
    return STATUS_OK;
}

int inst_exit_init(Instance *inst) {
    if (!inst_allowed(inst, "exitInitializationMode", ST_INITIALIZATION)) return STATUS_ERROR;
    if (rebuild(inst, 1) != STATUS_OK) return STATUS_ERROR;
    double u[MODEL_NU], s[MODEL_NU];
    memset(s, 0, sizeof s);
    inst->s.position = 0.0;
#if HAS_STANDALONE
    if (inst->s.b[VR_standalone - VR_BOOL_BASE]) {
        if (load_track(inst) != STATUS_OK) return STATUS_ERROR;
        inst->s.position = inst->s.r[VR_track_start];
        RailInputs rail;
        model_rail_inputs(inst->s.r, &rail);
        double s0[MODEL_NU], c0[MODEL_NU];
        if (track_inputs(inst, &rail, inst->s.position, inst->s.r[VR_speed], u, s0, c0) != STATUS_OK)
            return STATUS_ERROR;
        memcpy(s, s0, sizeof s);
    } else
#endif
    {
        if (check_inputs(inst) != STATUS_OK) return STATUS_ERROR;
        double c[MODEL_NU];
        inputs(inst, u, s, c); /* with the derivatives given in initialization mode, if any */
    }
    /* start in static equilibrium under the initial inputs (rates zero): A x = -B u_static */
    double Ax[MODEL_NX * MODEL_NX], bx[MODEL_NX];
    int piv[MODEL_NX];
    memcpy(Ax, inst->sys.A, sizeof Ax);
    for (int i = 0; i < MODEL_NX; i++) {
        double v = 0.0;
        for (int j = 0; j < MODEL_NU; j++)
            if (!INPUT_IS_RATE[j]) v -= inst->sys.B[i * MODEL_NU + j] * u[j]; /* levels, not rates */
        bx[i] = v;
    }
    if (la_lu(MODEL_NX, Ax, piv) == 0) {
        la_lu_solve(MODEL_NX, 1, Ax, piv, bx);
        memcpy(inst->s.x, bx, sizeof bx);
    } else {
        memset(inst->s.x, 0, sizeof inst->s.x);
    }
    outputs(inst, u, s);
    inst->s.outputs_stale = 0;
    inst->s.state = ST_STEP;
    return STATUS_OK;
}

int inst_terminate(Instance *inst) {
    if (!inst_allowed(inst, "terminate", ST_STEP | ST_INITIALIZATION)) return STATUS_ERROR;
    inst->s.state = ST_TERMINATED;
    return STATUS_OK;
}

/* ------------------------------------------------------------------ variables */

static int real_index(Instance *inst, unsigned vr, const char *function) {
    if (vr >= (unsigned)N_REALS) {
        inst_error(inst, 0, "%s: value reference %u is not a Float64/Real variable (0-%d)", function, vr,
                   N_REALS - 1);
        return -1;
    }
    return (int)vr;
}

int inst_set_real(Instance *inst, const unsigned *vr, size_t n, const double *value) {
    if (!inst_allowed(inst, "set real", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP)) return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "set real: null array");
    for (size_t k = 0; k < n; k++) {
        int i = real_index(inst, vr[k], "set real");
        if (i < 0) return STATUS_ERROR;
        const char kind = REAL_KIND[i];
        if (kind == 'y' || kind == 't')
            return inst_error(inst, 0, "%s is an %s and cannot be set", REAL_NAME[i],
                              kind == 'y' ? "output" : "independent variable");
        if (kind == 'f' && inst->s.state == ST_STEP)
            return inst_error(inst, 0, "%s is a fixed parameter: set it before the end of initialization",
                              REAL_NAME[i]);
        if (!isfinite(value[k]))
            return inst_error(inst, 0, "%s = %g is not finite; the value is not taken", REAL_NAME[i], value[k]);
        if (kind == 'p' || kind == 'f') {
            if (inst->s.r[i] != value[k]) inst->dirty = 1;
        }
        if (kind == 'u' || kind == 'p') inst->s.outputs_stale = 1;
        inst->s.r[i] = value[k];
    }
    return STATUS_OK;
}

int inst_get_real(Instance *inst, const unsigned *vr, size_t n, double *value) {
    if (!inst_allowed(inst, "get real", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP | ST_TERMINATED | ST_ERROR))
        return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "get real: null array");
    if (inst->s.state == ST_STEP && inst->s.outputs_stale && refresh_outputs(inst) != STATUS_OK) return STATUS_ERROR;
    for (size_t k = 0; k < n; k++) {
        int i = real_index(inst, vr[k], "get real");
        if (i < 0) return STATUS_ERROR;
        value[k] = inst->s.r[i];
    }
    return STATUS_OK;
}

int inst_set_bool(Instance *inst, const unsigned *vr, size_t n, const int *value) {
    if (!inst_allowed(inst, "set boolean", ST_INSTANTIATED | ST_INITIALIZATION)) return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "set boolean: null array");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < (unsigned)VR_BOOL_BASE || vr[k] >= (unsigned)VR_STRING_BASE)
            return inst_error(inst, 0, "set boolean: value reference %u is not a Boolean variable", vr[k]);
        inst->s.b[vr[k] - VR_BOOL_BASE] = value[k] != 0;
    }
    return STATUS_OK;
}

int inst_get_bool(Instance *inst, const unsigned *vr, size_t n, int *value) {
    if (!inst_allowed(inst, "get boolean", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP | ST_TERMINATED | ST_ERROR))
        return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "get boolean: null array");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < (unsigned)VR_BOOL_BASE || vr[k] >= (unsigned)VR_STRING_BASE)
            return inst_error(inst, 0, "get boolean: value reference %u is not a Boolean variable", vr[k]);
        value[k] = inst->s.b[vr[k] - VR_BOOL_BASE];
    }
    return STATUS_OK;
}

int inst_set_string(Instance *inst, const unsigned *vr, size_t n, const char *const *value) {
    if (!inst_allowed(inst, "set string", ST_INSTANTIATED | ST_INITIALIZATION)) return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "set string: null array");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < (unsigned)VR_STRING_BASE || vr[k] >= (unsigned)N_VARIABLES)
            return inst_error(inst, 0, "set string: value reference %u is not a String variable", vr[k]);
        const char *v = value[k] ? value[k] : "";
        char *copy = malloc(strlen(v) + 1);
        if (!copy) return inst_error(inst, 0, "set string: out of memory");
        strcpy(copy, v);
        free(inst->strings[vr[k] - VR_STRING_BASE]);
        inst->strings[vr[k] - VR_STRING_BASE] = copy;
    }
    return STATUS_OK;
}

int inst_get_string(Instance *inst, const unsigned *vr, size_t n, const char **value) {
    if (!inst_allowed(inst, "get string", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP | ST_TERMINATED | ST_ERROR))
        return STATUS_ERROR;
    if (n && (!vr || !value)) return inst_error(inst, 0, "get string: null array");
    for (size_t k = 0; k < n; k++) {
        if (vr[k] < (unsigned)VR_STRING_BASE || vr[k] >= (unsigned)N_VARIABLES)
            return inst_error(inst, 0, "get string: value reference %u is not a String variable", vr[k]);
        value[k] = inst->strings[vr[k] - VR_STRING_BASE];
    }
    return STATUS_OK;
}

int inst_set_input_derivatives(Instance *inst, const unsigned *vr, size_t n, const int *order, const double *value) {
    if (!inst_allowed(inst, "setRealInputDerivatives", ST_INITIALIZATION | ST_STEP)) return STATUS_ERROR;
    if (n && (!vr || !order || !value)) return inst_error(inst, 0, "setRealInputDerivatives: null array");
    for (size_t k = 0; k < n; k++) {
        int j = -1;
        for (int q = 0; q < MODEL_NU; q++)
            if ((unsigned)INPUT_VR[q] == vr[k]) j = q;
        if (j < 0) return inst_error(inst, 0, "setRealInputDerivatives: value reference %u is not an input", vr[k]);
        if (order[k] < 1) return inst_error(inst, 0, "setRealInputDerivatives: order %d < 1", order[k]);
        if (!isfinite(value[k]))
            return inst_error(inst, 0, "derivative of %s = %g is not finite", REAL_NAME[vr[k]], value[k]);
        if (order[k] > 2) continue; /* the step is exact for inputs quadratic over it */
        if (INPUT_RATE_INDEX[j] >= 0) continue; /* a level's derivatives are its rate input's */
        inst->s.outputs_stale = 1;
        if (order[k] == 1) {
            inst->s.du[j] = value[k];
            inst->s.du_set[j] = 1;
        } else {
            inst->s.du2[j] = value[k];
            inst->s.du2_set[j] = 1;
        }
    }
    return STATUS_OK;
}

/* ------------------------------------------------------------------ stepping */

static void advance(Instance *inst, const Discretisation *d, const double *u, const double *s, const double *c) {
    double xn[MODEL_NX];
    la_matvec_acc(MODEL_NX, MODEL_NX, d->Phi, inst->s.x, 0.0, xn);
    la_matvec_acc(MODEL_NX, MODEL_NU, d->G0, u, 1.0, xn);
    la_matvec_acc(MODEL_NX, MODEL_NU, d->G1, s, 1.0, xn);
    la_matvec_acc(MODEL_NX, MODEL_NU, d->G2, c, 1.0, xn);
    memcpy(inst->s.x, xn, sizeof xn);
}

int inst_do_step(Instance *inst, double t, double h) {
    if (!inst_allowed(inst, "doStep", ST_STEP)) return STATUS_ERROR;
    if (!isfinite(t) || !isfinite(h) || !(h > 0.0))
        return inst_error(inst, 0, "doStep(%g, %g): the communication point must be finite and the step size "
                          "positive", t, h);
    if (fabs(t - inst->s.time) > 1e-9 * fmax(1.0, fabs(t)))
        return inst_error(inst, 0, "doStep at t = %.17g but the FMU is at t = %.17g", t, inst->s.time);
    if (inst->dirty && rebuild(inst, 1) != STATUS_OK) return STATUS_ERROR;
    double u[MODEL_NU], s[MODEL_NU], c[MODEL_NU];
    memset(c, 0, sizeof c);
#if HAS_STANDALONE
    if (inst->s.b[VR_standalone - VR_BOOL_BASE]) {
        const double v = inst->s.r[VR_speed];
        if (!isfinite(v)) return inst_error(inst, 1, "input speed is not finite");
        RailInputs rail;
        model_rail_inputs(inst->s.r, &rail);
        const double dx = inst->track.min_spacing;
        double nsub = ceil(fabs(v) * h / dx);
        if (nsub < 1) nsub = 1;
        if (nsub > MAX_SUBSTEPS)
            return inst_error(inst, 1, "doStep: %g s at %g m/s crosses more than %d track points; take smaller "
                              "steps", h, v, MAX_SUBSTEPS);
        const int n = (int)nsub;
        const double hs = h / n;
        const Discretisation *d = discretise(inst, hs);
        if (!d) return inst_error(inst, 1, "doStep: the discretisation for h = %g s failed", hs);
        /* Rail inputs over each substep: value and rate at its start, curvature fitted to the
         * value at its end (exact for the spline's quadratic rates, never evaluating the
         * third derivative, which jumps at the profile points) */
        double ub[MODEL_NU], sb[MODEL_NU], cb[MODEL_NU];
        if (track_inputs(inst, &rail, inst->s.position, v, u, s, c) != STATUS_OK) return STATUS_ERROR;
        double u0[MODEL_NU], s0[MODEL_NU], c0[MODEL_NU];
        memcpy(u0, u, sizeof u0), memcpy(s0, s, sizeof s0);
        for (int j = 0; j < MODEL_NU; j++) c0[j] = inst->s.du2_set[j] ? inst->s.du2[j] : 0.0;
        for (int k = 1; k <= n; k++) {
            const double tau = hs * k;
            if (track_inputs(inst, &rail, inst->s.position + v * tau, v, ub, sb, cb) != STATUS_OK)
                return STATUS_ERROR;
            for (int j = 0; j < MODEL_NU; j++) {
                if (rail.kind[j] == MODEL_RAIL_NONE) { /* other inputs go on along their derivatives */
                    const double t0 = tau - hs;
                    u[j] = u0[j] + (s0[j] + 0.5 * c0[j] * t0) * t0;
                    s[j] = s0[j] + c0[j] * t0;
                    c[j] = c0[j];
                    ub[j] = u0[j] + (s0[j] + 0.5 * c0[j] * tau) * tau;
                    sb[j] = s0[j] + c0[j] * tau;
                } else {
                    c[j] = 2.0 * (ub[j] - u[j] - s[j] * hs) / (hs * hs);
                }
            }
            advance(inst, d, u, s, c);
            memcpy(u, ub, sizeof u), memcpy(s, sb, sizeof s);
        }
        inst->s.position += v * h;
        /* u, s: inputs at the end of the step and their rates, for the outputs */
    } else
#endif
    {
        if (check_inputs(inst) != STATUS_OK) return STATUS_ERROR;
        inputs(inst, u, s, c);
        const Discretisation *d = discretise(inst, h);
        if (!d) return inst_error(inst, 1, "doStep: the discretisation for h = %g s failed", h);
        advance(inst, d, u, s, c);
        for (int j = 0; j < MODEL_NU; j++) {
            inst->s.u_prev[j] = u[j];
            u[j] += (s[j] + 0.5 * c[j] * h) * h; /* extrapolated to the end of the step */
            s[j] += c[j] * h;
        }
        inst->s.h_prev = h;
    }
    for (int j = 0; j < MODEL_NX; j++)
        if (!isfinite(inst->s.x[j])) return inst_error(inst, 1, "doStep: the state became non-finite");
    inst->s.time = t + h;
    inst->s.r[VR_time] = inst->s.time;
    outputs(inst, u, s);
    inst->s.outputs_stale = 0;
    memset(inst->s.du, 0, sizeof inst->s.du); /* derivatives are given anew for every step */
    memset(inst->s.du_set, 0, sizeof inst->s.du_set);
    memset(inst->s.du2, 0, sizeof inst->s.du2);
    memset(inst->s.du2_set, 0, sizeof inst->s.du2_set);
    return STATUS_OK;
}

/* ------------------------------------------------------------------ FMU states */

size_t inst_state_size(void) { return sizeof(Snapshot); }

int inst_get_state(Instance *inst, void **state) {
    if (!inst_allowed(inst, "getFMUState", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP | ST_TERMINATED | ST_ERROR))
        return STATUS_ERROR;
    if (!state) return inst_error(inst, 0, "getFMUState: null pointer");
    Snapshot *snap = *state ? (Snapshot *)*state : malloc(sizeof(Snapshot));
    if (!snap) return inst_error(inst, 0, "getFMUState: out of memory");
    if (*state && snap->magic != SNAPSHOT_MAGIC) return inst_error(inst, 0, "getFMUState: not a state of this FMU");
    *snap = inst->s;
    *state = snap;
    return STATUS_OK;
}

int inst_set_state(Instance *inst, const void *state) {
    if (!inst_allowed(inst, "setFMUState", ST_INSTANTIATED | ST_INITIALIZATION | ST_STEP | ST_TERMINATED | ST_ERROR))
        return STATUS_ERROR;
    const Snapshot *snap = (const Snapshot *)state;
    if (!snap || snap->magic != SNAPSHOT_MAGIC) return inst_error(inst, 0, "setFMUState: not a state of this FMU");
    if (snap->state != ST_INSTANTIATED && snap->state != ST_INITIALIZATION && snap->state != ST_STEP &&
        snap->state != ST_TERMINATED && snap->state != ST_ERROR)
        return inst_error(inst, 0, "setFMUState: the state holds an invalid mode %d", (int)snap->state);
    const int rebuild_needed = memcmp(snap->r, inst->s.r, sizeof snap->r) != 0;
    inst->s = *snap;
    if (rebuild_needed) inst->dirty = 1;
#if HAS_STANDALONE
    if (inst->s.b[VR_standalone - VR_BOOL_BASE] && inst->s.state == ST_STEP && !inst->track_loaded &&
        load_track(inst) != STATUS_OK)
        return STATUS_ERROR;
#endif
    return STATUS_OK;
}

int inst_free_state(Instance *inst, void **state) {
    (void)inst;
    if (state && *state) {
        free(*state);
        *state = NULL;
    }
    return STATUS_OK;
}

int inst_serialize(Instance *inst, const void *state, char *bytes, size_t size) {
    const Snapshot *snap = (const Snapshot *)state;
    if (!snap || snap->magic != SNAPSHOT_MAGIC) return inst_error(inst, 0, "serializeFMUState: not a state of this FMU");
    if (!bytes || size < sizeof(Snapshot))
        return inst_error(inst, 0, "serializeFMUState: buffer of %zu bytes, %zu needed", size, sizeof(Snapshot));
    memcpy(bytes, snap, sizeof(Snapshot));
    return STATUS_OK;
}

int inst_deserialize(Instance *inst, const char *bytes, size_t size, void **state) {
    if (!bytes || !state || size != sizeof(Snapshot))
        return inst_error(inst, 0, "deserializeFMUState: %zu bytes, %zu expected", size, sizeof(Snapshot));
    Snapshot tmp;
    memcpy(&tmp, bytes, sizeof tmp);
    if (tmp.magic != SNAPSHOT_MAGIC) return inst_error(inst, 0, "deserializeFMUState: not a state of this FMU");
    Snapshot *snap = *state ? (Snapshot *)*state : malloc(sizeof(Snapshot));
    if (!snap) return inst_error(inst, 0, "deserializeFMUState: out of memory");
    *snap = tmp;
    *state = snap;
    return STATUS_OK;
}

/* ------------------------------------------------------------------ registry */

#define REGISTRY_SIZE 4096
static Instance *registry[REGISTRY_SIZE];
static atomic_flag registry_lock = ATOMIC_FLAG_INIT;

static void lock(void) {
    while (atomic_flag_test_and_set_explicit(&registry_lock, memory_order_acquire)) {
    }
}
static void unlock(void) { atomic_flag_clear_explicit(&registry_lock, memory_order_release); }

int registry_add(Instance *inst) {
    int ok = 0;
    lock();
    for (int i = 0; i < REGISTRY_SIZE; i++)
        if (!registry[i]) {
            registry[i] = inst;
            ok = 1;
            break;
        }
    unlock();
    return ok;
}

int registry_remove(Instance *inst) {
    int found = 0;
    lock();
    for (int i = 0; i < REGISTRY_SIZE; i++)
        if (inst && registry[i] == inst) {
            registry[i] = NULL;
            found = 1;
            break;
        }
    unlock();
    return found;
}

int registry_live(const void *inst) {
    int found = 0;
    if (!inst) return 0;
    lock();
    for (int i = 0; i < REGISTRY_SIZE; i++)
        if (registry[i] == inst) {
            found = 1;
            break;
        }
    unlock();
    return found;
}

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

void uri_to_path(const char *uri, char *path, size_t len) {
    if (!len) return;
    path[0] = '\0';
    if (!uri) return;
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
#ifdef _WIN32
        if (p[0] == '/' && p[1] && p[2] == ':') p++; /* file:///C:/... */
#endif
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
    size_t k = 0;
    while (*p && k + 1 < len) {
        if (p[0] == '%' && hexval(p[1]) >= 0 && hexval(p[2]) >= 0) {
            path[k++] = (char)(hexval(p[1]) * 16 + hexval(p[2]));
            p += 3;
        } else {
            path[k++] = *p++;
        }
    }
    while (k > 1 && (path[k - 1] == '/' || path[k - 1] == '\\')) k--; /* no trailing separator */
    path[k] = '\0';
}
