/* The box-type vehicle: the calibrated carbody in its free-free modes below the export's
 * cut-off plus residual-flexibility pseudo-modes (static correction), the rigid bodies with
 * their free DOF (two bogies with six; an extended model's equipment with its vertical one),
 * the suspension elements, and the wheelsets held to the rail by the axle boxes
 * (calibration/models/box/vehicle_reduction.py builds these matrices; model_data.h carries them).
 *
 *     M q'' + (C_s + C_c(zeta)) q' + K q = B_k z + B_c dz + b_f F,    y = S q''
 *
 * Only the carbody's structural damping C_c = diag(2 zeta omega) on its elastic
 * coordinates is assembled here, from the tunable zeta_carbody. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "model_data.h"

#define NQ BOX_NQ

int model_build(const double *r, LtiSystem *sys, char *msg, size_t msg_len) {
    const double zeta = r[VR_zeta_carbody];
    if (!isfinite(zeta) || zeta < 0 || zeta >= 1) {
        snprintf(msg, msg_len, "zeta_carbody = %g must be in [0, 1)", zeta);
        return -1;
    }
    if (MODEL_NX != 2 * NQ || MODEL_NU != 9 || MODEL_NY != BOX_NS) {
        snprintf(msg, msg_len, "model_config.h and model_data.h disagree on sizes");
        return -1;
    }
    for (int j = 0; j < 4; j++)
        if (INPUT_VR[j] != VR_z_rail_1 + j || INPUT_VR[4 + j] != VR_dz_rail_1 + j || INPUT_VR[8] != VR_exciter_force) {
            snprintf(msg, msg_len, "model_config.h: inputs must be z_rail_1..4, dz_rail_1..4, exciter_force");
            return -1;
        }
    memset(sys, 0, sizeof *sys);
    for (int i = 0; i < NQ; i++) {
        const double minv = 1.0 / BOX_M[i];
        sys->A[i * MODEL_NX + NQ + i] = 1.0;
        double *arow = sys->A + (NQ + i) * MODEL_NX;
        for (int j = 0; j < NQ; j++) {
            arow[j] = -minv * BOX_K[i * NQ + j];
            arow[NQ + j] = -minv * BOX_CS[i * NQ + j];
        }
        if (BOX_ELASTIC[i]) arow[NQ + i] -= minv * 2.0 * zeta * BOX_OMEGA[i];
        double *brow = sys->B + (NQ + i) * MODEL_NU;
        for (int j = 0; j < 4; j++) {
            brow[j] = minv * BOX_BK[i * 4 + j];
            brow[4 + j] = minv * BOX_BC[i * 4 + j];
        }
        brow[8] = minv * BOX_BF[i];
    }
    /* floor accelerations: S q'' = S (rows NQ.. of A and B) */
    for (int o = 0; o < MODEL_NY; o++) {
        double *crow = sys->C + o * MODEL_NX, *drow = sys->D + o * MODEL_NU;
        for (int i = 0; i < NQ; i++) {
            const double s = BOX_S[o * NQ + i];
            if (s == 0.0) continue;
            const double *arow = sys->A + (NQ + i) * MODEL_NX, *brow = sys->B + (NQ + i) * MODEL_NU;
            for (int j = 0; j < MODEL_NX; j++) crow[j] += s * arow[j];
            for (int j = 0; j < MODEL_NU; j++) drow[j] += s * brow[j];
        }
    }
    return 0;
}

void model_rail_inputs(const double *r, RailInputs *rail) {
    (void)r;
    for (int j = 0; j < MODEL_NU; j++) rail->kind[j] = MODEL_RAIL_NONE, rail->offset[j] = 0.0;
    for (int j = 0; j < 4; j++) {
        rail->kind[j] = 0, rail->offset[j] = BOX_WHEEL_X[j];
        rail->kind[4 + j] = 1, rail->offset[4 + j] = BOX_WHEEL_X[j];
    }
}
