/* A minimal FMI 2.0 co-simulation master for measuring an FMU's own cost: it loads the
 * binary, runs it stand-alone (or with sinusoidal inputs it computes itself) at a fixed
 * communication step, reads every output after each step as a master would, and prints
 * the wall time as JSON.
 *
 *   fmu_driver LIB RESOURCE_URI GUID STEPS H MODE VR_SPEED SPEED VR_TRACK_START START
 *              N_OUT VR_OUT... [N_IN VR_IN...]
 *
 * MODE "standalone": speed and track start are set, the FMU reads its own track;
 * MODE "inputs": the standalone parameter is left as built (false) and the N_IN inputs
 * get a sine of 1 mm at 2 Hz (level inputs) every step. */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    fprintf(stderr, "[%s] %s %d: %s\n", name, category, (int)status, message);
}

#define LOAD(name)                                                       \
    name##TYPE *name = (name##TYPE *)dlsym(lib, #name);                  \
    if (!name) {                                                         \
        fprintf(stderr, "missing %s\n", #name);                          \
        return 2;                                                        \
    }

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 12) {
        fprintf(stderr, "usage: see the header of fmu_driver.c\n");
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep) LOAD(fmi2GetReal) LOAD(fmi2SetReal) LOAD(fmi2Terminate)
    LOAD(fmi2FreeInstance)
    const long steps = atol(argv[4]);
    const double h = atof(argv[5]);
    const int standalone = strcmp(argv[6], "standalone") == 0;
    const fmi2ValueReference vr_speed = (fmi2ValueReference)atol(argv[7]);
    const double speed = atof(argv[8]);
    const fmi2ValueReference vr_start = (fmi2ValueReference)atol(argv[9]);
    const double start = atof(argv[10]);
    const int n_out = atoi(argv[11]);
    if (argc < 12 + n_out) return 2;
    fmi2ValueReference *vr_out = malloc(sizeof(fmi2ValueReference) * (n_out + 1));
    double *y = malloc(sizeof(double) * (n_out + 1));
    for (int i = 0; i < n_out; i++) vr_out[i] = (fmi2ValueReference)atol(argv[12 + i]);
    int n_in = 0;
    fmi2ValueReference vr_in[64];
    double u[64];
    if (!standalone && argc > 12 + n_out) {
        n_in = atoi(argv[12 + n_out]);
        if (n_in > 64) return 2;
        for (int i = 0; i < n_in; i++) vr_in[i] = (fmi2ValueReference)atol(argv[13 + n_out + i]);
    }
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("driver", fmi2CoSimulation, argv[3], argv[2], &cb, fmi2False, fmi2False);
    if (!c) return 1;
    if (standalone) {
        fmi2SetReal(c, &vr_speed, 1, &speed);
        fmi2SetReal(c, &vr_start, 1, &start);
    }
    if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning) return 1;
    if (fmi2EnterInitializationMode(c) > fmi2Warning) return 1;
    if (fmi2ExitInitializationMode(c) > fmi2Warning) return 1;
    double checksum = 0.0;
    const double t0 = now();
    for (long k = 0; k < steps; k++) {
        const double t = k * h;
        if (n_in) {
            for (int i = 0; i < n_in; i++) u[i] = 1e-3 * sin(12.566370614359172 * t + i) /* 2 Hz */;
            fmi2SetReal(c, vr_in, n_in, u);
        }
        if (fmi2DoStep(c, t, h, fmi2True) != fmi2OK) {
            fprintf(stderr, "doStep failed at t = %g\n", t);
            return 1;
        }
        fmi2GetReal(c, vr_out, n_out, y);
        checksum += y[0];
    }
    const double wall = now() - t0;
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    printf("{\"steps\": %ld, \"step_s\": %g, \"simulated_s\": %.6f, \"wall_s\": %.6f, \"real_time_factor\": %.1f, "
           "\"us_per_step\": %.4f, \"checksum\": %.17g}\n",
           steps, h, steps * h, wall, steps * h / wall, 1e6 * wall / steps, checksum);
    free(vr_out);
    free(y);
    return 0;
}
