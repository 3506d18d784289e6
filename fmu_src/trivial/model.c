/* The smallest model the shared layer runs: one first-order lag y' = (u - y) / tau.
 * It exists to measure what an importer costs per step on its own (scripts/bench_fmu.py):
 * the same loop over this FMU and over the car FMU differ by the car's own work. */
#include <stdio.h>
#include <string.h>

#include "model.h"

int model_build(const double *r, LtiSystem *sys, char *msg, size_t msg_len) {
    const double tau = r[VR_tau];
    if (!(tau > 0)) {
        snprintf(msg, msg_len, "tau = %g must be > 0", tau);
        return -1;
    }
    memset(sys, 0, sizeof *sys);
    sys->A[0] = -1.0 / tau;
    sys->B[0] = 1.0 / tau;
    for (int i = 0; i < MODEL_NY; i++) sys->C[i] = 1.0;
    return 0;
}

void model_rail_inputs(const double *r, RailInputs *rail) {
    (void)r;
    rail->kind[0] = MODEL_RAIL_NONE;
    rail->offset[0] = 0.0;
}
