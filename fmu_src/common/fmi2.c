/* FMI 2.0 co-simulation interface over the shared instance (instance.c). */
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"

#define CHECK(c, fn)                                                                          \
    Instance *inst = (Instance *)(c);                                                         \
    if (!registry_live(inst)) return fmi2Error; /* freed, foreign or null: nothing to touch */ \
    (void)fn

/* The message is passed as the format string, its '%' doubled: importers that cannot
 * expand varargs (ctypes-based ones such as fmpy) still show the text. */
static void log_fmi2(Instance *inst, int status, const char *category, const char *message) {
    fmi2CallbackLogger logger = (fmi2CallbackLogger)inst->logger;
    if (!logger) return;
    char escaped[2048];
    size_t k = 0;
    for (const char *p = message; *p && k + 2 < sizeof escaped; p++) {
        if (*p == '%') escaped[k++] = '%';
        escaped[k++] = *p;
    }
    escaped[k] = '\0';
    logger((fmi2ComponentEnvironment)inst->env, inst->name, (fmi2Status)status, category, escaped);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    CHECK(c, "fmi2SetDebugLogging");
    (void)nCategories;
    (void)categories;
    inst->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    fmi2CallbackLogger logger = functions ? functions->logger : NULL;
    void *env = functions ? functions->componentEnvironment : NULL;
    const char *name = instanceName ? instanceName : "";
    if (fmuType != fmi2CoSimulation) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "%s", "this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0) {
        if (logger)
            logger(env, name, fmi2Error, "logStatusError", "GUID %s does not match the FMU's %s",
                   fmuGUID ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    char path[4096];
    uri_to_path(fmuResourceLocation, path, sizeof path);
    Instance *inst = inst_new(name, path, 2, log_fmi2, env, loggingOn != fmi2False);
    if (!inst) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "%s", "out of memory");
        return NULL;
    }
    inst->logger = (void (*)(void))logger;
    if (!registry_add(inst)) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "%s", "too many instances");
        inst_free(inst);
        return NULL;
    }
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (registry_remove(inst)) inst_free(inst); /* a second free finds nothing: harmless */
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK(c, "fmi2SetupExperiment");
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!inst_allowed(inst, "fmi2SetupExperiment", ST_INSTANTIATED)) return fmi2Error;
    if (!(startTime == startTime) || startTime > 1e300 || startTime < -1e300)
        return (fmi2Status)inst_error(inst, 0, "fmi2SetupExperiment: start time %g is not finite", startTime);
    inst->s.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2EnterInitializationMode");
    return (fmi2Status)inst_enter_init(inst, inst->s.time);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2ExitInitializationMode");
    return (fmi2Status)inst_exit_init(inst);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(c, "fmi2Terminate");
    return (fmi2Status)inst_terminate(inst);
}

fmi2Status fmi2Reset(fmi2Component c) {
    CHECK(c, "fmi2Reset");
    return (fmi2Status)inst_reset(inst);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    CHECK(c, "fmi2GetReal");
    return (fmi2Status)inst_get_real(inst, vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    CHECK(c, "fmi2SetReal");
    return (fmi2Status)inst_set_real(inst, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    CHECK(c, "fmi2GetInteger");
    (void)value;
    if (nvr == 0) return fmi2OK;
    return (fmi2Status)inst_error(inst, 0, "fmi2GetInteger: value reference %u: this FMU has no Integer variables",
                                  vr ? vr[0] : 0u);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    CHECK(c, "fmi2SetInteger");
    (void)value;
    if (nvr == 0) return fmi2OK;
    return (fmi2Status)inst_error(inst, 0, "fmi2SetInteger: value reference %u: this FMU has no Integer variables",
                                  vr ? vr[0] : 0u);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    CHECK(c, "fmi2GetBoolean");
    if (nvr && (!vr || !value)) return (fmi2Status)inst_error(inst, 0, "fmi2GetBoolean: null array");
    for (size_t k = 0; k < nvr; k++) {
        int v;
        int st = inst_get_bool(inst, &vr[k], 1, &v);
        if (st != STATUS_OK) return (fmi2Status)st;
        value[k] = v ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    CHECK(c, "fmi2SetBoolean");
    if (nvr && (!vr || !value)) return (fmi2Status)inst_error(inst, 0, "fmi2SetBoolean: null array");
    for (size_t k = 0; k < nvr; k++) {
        int v = value[k] != fmi2False;
        int st = inst_set_bool(inst, &vr[k], 1, &v);
        if (st != STATUS_OK) return (fmi2Status)st;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    CHECK(c, "fmi2GetString");
    return (fmi2Status)inst_get_string(inst, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    CHECK(c, "fmi2SetString");
    return (fmi2Status)inst_set_string(inst, vr, nvr, value);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2GetFMUstate");
    return (fmi2Status)inst_get_state(inst, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK(c, "fmi2SetFMUstate");
    return (fmi2Status)inst_set_state(inst, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2FreeFMUstate");
    return (fmi2Status)inst_free_state(inst, FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    CHECK(c, "fmi2SerializedFMUstateSize");
    (void)FMUstate;
    if (!size) return (fmi2Status)inst_error(inst, 0, "fmi2SerializedFMUstateSize: null pointer");
    *size = inst_state_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    CHECK(c, "fmi2SerializeFMUstate");
    return (fmi2Status)inst_serialize(inst, FMUstate, serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2DeSerializeFMUstate");
    return (fmi2Status)inst_deserialize(inst, serializedState, size, FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    CHECK(c, "fmi2GetDirectionalDerivative");
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return (fmi2Status)inst_error(inst, 0, "fmi2GetDirectionalDerivative: not provided by this FMU");
}

/* ----------------------------------------------------------- model exchange: not provided */
#define NOT_ME(fn)                                                                              \
    CHECK(c, fn);                                                                               \
    return (fmi2Status)inst_error(inst, 0, "%s: this FMU is co-simulation only", fn)

fmi2Status fmi2EnterEventMode(fmi2Component c) { NOT_ME("fmi2EnterEventMode"); }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    (void)info;
    NOT_ME("fmi2NewDiscreteStates");
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { NOT_ME("fmi2EnterContinuousTimeMode"); }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    NOT_ME("fmi2CompletedIntegratorStep");
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    (void)time;
    NOT_ME("fmi2SetTime");
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    (void)x, (void)nx;
    NOT_ME("fmi2SetContinuousStates");
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    (void)derivatives, (void)nx;
    NOT_ME("fmi2GetDerivatives");
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators, (void)ni;
    NOT_ME("fmi2GetEventIndicators");
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    (void)x, (void)nx;
    NOT_ME("fmi2GetContinuousStates");
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    (void)x_nominal, (void)nx;
    NOT_ME("fmi2GetNominalsOfContinuousStates");
}

/* ----------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    CHECK(c, "fmi2SetRealInputDerivatives");
    int ord[64];
    for (size_t k = 0; k < nvr; k += 64) {
        size_t m = nvr - k < 64 ? nvr - k : 64;
        if (!order || !vr || !value) return (fmi2Status)inst_error(inst, 0, "fmi2SetRealInputDerivatives: null array");
        for (size_t q = 0; q < m; q++) ord[q] = order[k + q];
        int st = inst_set_input_derivatives(inst, vr + k, m, ord, value + k);
        if (st != STATUS_OK) return (fmi2Status)st;
    }
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    CHECK(c, "fmi2GetRealOutputDerivatives");
    (void)vr, (void)order, (void)value;
    if (nvr == 0) return fmi2OK;
    return (fmi2Status)inst_error(inst, 0, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder 0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CHECK(c, "fmi2DoStep");
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)inst_do_step(inst, currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    CHECK(c, "fmi2CancelStep");
    return (fmi2Status)inst_error(inst, 0, "fmi2CancelStep: steps are never asynchronous here");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    CHECK(c, "fmi2GetStatus");
    (void)s;
    if (!value) return fmi2Error;
    *value = inst->s.state == ST_ERROR ? fmi2Error : fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK(c, "fmi2GetRealStatus");
    if (s != fmi2LastSuccessfulTime || !value)
        return (fmi2Status)inst_error(inst, 0, "fmi2GetRealStatus: only fmi2LastSuccessfulTime is provided");
    *value = inst->s.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    CHECK(c, "fmi2GetIntegerStatus");
    (void)s, (void)value;
    return (fmi2Status)inst_error(inst, 0, "fmi2GetIntegerStatus: not provided");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK(c, "fmi2GetBooleanStatus");
    if (s != fmi2Terminated || !value)
        return (fmi2Status)inst_error(inst, 0, "fmi2GetBooleanStatus: only fmi2Terminated is provided");
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    CHECK(c, "fmi2GetStringStatus");
    (void)s, (void)value;
    return (fmi2Status)inst_error(inst, 0, "fmi2GetStringStatus: not provided");
}
