/* The FMU instance shared by the FMI 2.0 and FMI 3.0 layers: variables, state machine,
 * exact stepping of the model's linear system, stand-alone track running, FMU states.
 *
 * Every entry point checks the state machine, its arguments and every value it is given;
 * a bad call returns STATUS_ERROR with a logged message naming what and where, and never
 * touches memory it does not own. */
#ifndef RAILCAL_INSTANCE_H
#define RAILCAL_INSTANCE_H

#include <stddef.h>

#include "model.h"
#include "track.h"

enum { STATUS_OK = 0, STATUS_WARNING = 1, STATUS_DISCARD = 2, STATUS_ERROR = 3, STATUS_FATAL = 4 };

typedef enum {
    ST_INSTANTIATED = 1,
    ST_INITIALIZATION = 2,
    ST_STEP = 4,
    ST_TERMINATED = 8,
    ST_ERROR = 16
} InstanceState;

#define CACHE_SIZE 8
#define MODEL_NA (MODEL_NX + 3 * MODEL_NU) /* augmented matrix for the exact discretisation */

typedef struct {
    double h;  /* step size [s]; 0: empty */
    unsigned long used;
    double Phi[MODEL_NX * MODEL_NX];
    double G0[MODEL_NX * MODEL_NU];
    double G1[MODEL_NX * MODEL_NU];
    double G2[MODEL_NX * MODEL_NU];
} Discretisation;

typedef struct Instance Instance;
typedef void (*LogFunction)(Instance *inst, int status, const char *category, const char *message);

/* What an FMU state holds: everything that evolves or is set. */
typedef struct {
    unsigned magic;
    InstanceState state;
    double time, position;
    double r[N_REALS];
    int b[N_BOOLS > 0 ? N_BOOLS : 1];
    double x[MODEL_NX];
    double du[MODEL_NU]; /* input derivatives given for the next step (FMI 2) */
    int du_set[MODEL_NU];
    double du2[MODEL_NU];    /* second derivatives given for the next step (FMI 2) */
    int du2_set[MODEL_NU];
    double u_prev[MODEL_NU]; /* inputs at the previous communication point */
    double h_prev;           /* the previous step size; 0 before the first step */
    int outputs_stale;       /* inputs set since the outputs were computed (direct feedthrough) */
} Snapshot;

struct Instance {
    char name[256];
    char resource_dir[4096];
    int fmi_version;
    int logging_on;
    LogFunction log;
    void *env;         /* the importer's environment pointer */
    void (*logger)(void); /* the importer's logger, cast back by the FMI layer */
    Snapshot s;
    char *strings[N_STRINGS > 0 ? N_STRINGS : 1];
    int dirty;         /* parameters changed since the system was built */
    LtiSystem sys;
    Discretisation cache[CACHE_SIZE];
    unsigned long clock;
    Track track;
    int track_loaded;
    int track_hint[MODEL_NU]; /* last profile segment of each rail input */
    double work[7 * MODEL_NA * MODEL_NA + MODEL_NA];
    double aug[MODEL_NA * MODEL_NA];
    double expA[MODEL_NA * MODEL_NA];
    int piv[MODEL_NA];
};

Instance *inst_new(const char *name, const char *resource_dir, int fmi_version, LogFunction log, void *env,
                   int logging_on);
void inst_free(Instance *inst);
int inst_reset(Instance *inst);
int inst_enter_init(Instance *inst, double start_time);
int inst_exit_init(Instance *inst);
int inst_terminate(Instance *inst);
int inst_set_real(Instance *inst, const unsigned *vr, size_t n, const double *value);
int inst_get_real(Instance *inst, const unsigned *vr, size_t n, double *value);
int inst_set_bool(Instance *inst, const unsigned *vr, size_t n, const int *value);
int inst_get_bool(Instance *inst, const unsigned *vr, size_t n, int *value);
int inst_set_string(Instance *inst, const unsigned *vr, size_t n, const char *const *value);
int inst_get_string(Instance *inst, const unsigned *vr, size_t n, const char **value);
int inst_set_input_derivatives(Instance *inst, const unsigned *vr, size_t n, const int *order, const double *value);
int inst_do_step(Instance *inst, double t, double h);
int inst_get_state(Instance *inst, void **state);
int inst_set_state(Instance *inst, const void *state);
int inst_free_state(Instance *inst, void **state);
size_t inst_state_size(void);
int inst_serialize(Instance *inst, const void *state, char *bytes, size_t size);
int inst_deserialize(Instance *inst, const char *bytes, size_t size, void **state);
/* log an error and return STATUS_ERROR; an error in a mode that changes the instance
 * (doStep, initialisation) also puts the instance into the error state */
int inst_error(Instance *inst, int enter_error_state, const char *fmt, ...);
int inst_allowed(Instance *inst, const char *function, int states);

/* Registry of live instances, so that a call with a freed or foreign pointer (and a second
 * free) is refused instead of touching freed memory. Thread-safe. */
int registry_add(Instance *inst);
int registry_remove(Instance *inst); /* 1 if it was live */
int registry_live(const void *inst);
/* file path from an FMI 2 resource URI (file:///... or a plain path) */
void uri_to_path(const char *uri, char *path, size_t len);

#endif
