/* FMI 3.0 co-simulation interface over the shared instance (instance.c). Every function of
 * fmi3Functions.h is exported; those of interface types this FMU does not declare (model
 * exchange, scheduled execution, clocks) and types it has no variables of refuse with a
 * logged error. */
#include <stdio.h>
#include <string.h>

#include "fmi3Functions.h"
#include "instance.h"

#define CHECK(i)                                  \
    Instance *inst = (Instance *)(i);             \
    if (!registry_live(inst)) return fmi3Error

static void log_fmi3(Instance *inst, int status, const char *category, const char *message) {
    fmi3LogMessageCallback logger = (fmi3LogMessageCallback)inst->logger;
    if (logger) logger((fmi3InstanceEnvironment)inst->env, (fmi3Status)status, category, message);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    CHECK(instance);
    (void)nCategories, (void)categories;
    inst->logging_on = loggingOn != fmi3False;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU is co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    if (eventModeUsed) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU has no event mode (hasEventMode false)");
        return NULL;
    }
    if (!instantiationToken || strcmp(instantiationToken, MODEL_GUID) != 0) {
        if (logMessage) {
            char msg[512];
            snprintf(msg, sizeof msg, "instantiation token %s does not match the FMU's %s",
                     instantiationToken ? instantiationToken : "(null)", MODEL_GUID);
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", msg);
        }
        return NULL;
    }
    char path[4096];
    uri_to_path(resourcePath, path, sizeof path); /* a plain path in FMI 3; tolerate a URI */
    Instance *inst = inst_new(instanceName, path, 3, log_fmi3, instanceEnvironment, loggingOn != fmi3False);
    if (!inst) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "out of memory");
        return NULL;
    }
    inst->logger = (void (*)(void))logMessage;
    if (!registry_add(inst)) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "too many instances");
        inst_free(inst);
        return NULL;
    }
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU is co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (registry_remove(inst)) inst_free(inst);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK(instance);
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    return (fmi3Status)inst_enter_init(inst, startTime);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK(instance);
    return (fmi3Status)inst_exit_init(inst);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK(instance);
    return (fmi3Status)inst_error(inst, 0, "fmi3EnterEventMode: this FMU has no event mode");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK(instance);
    return (fmi3Status)inst_terminate(inst);
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK(instance);
    return (fmi3Status)inst_reset(inst);
}

/* ----------------------------------------------------------- variables */

static fmi3Status scalars(Instance *inst, const char *fn, size_t nvr, size_t nValues) {
    if (nvr != nValues)
        return (fmi3Status)inst_error(inst, 0, "%s: %zu value references but %zu values (all variables are scalars)",
                                      fn, nvr, nValues);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3GetFloat64", nvr, nValues) != fmi3OK) return fmi3Error;
    return (fmi3Status)inst_get_real(inst, vr, nvr, values);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3SetFloat64", nvr, nValues) != fmi3OK) return fmi3Error;
    return (fmi3Status)inst_set_real(inst, vr, nvr, values);
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3GetBoolean", nvr, nValues) != fmi3OK) return fmi3Error;
    if (nvr && (!vr || !values)) return (fmi3Status)inst_error(inst, 0, "fmi3GetBoolean: null array");
    for (size_t k = 0; k < nvr; k++) {
        int v;
        int st = inst_get_bool(inst, &vr[k], 1, &v);
        if (st != STATUS_OK) return (fmi3Status)st;
        values[k] = v ? fmi3True : fmi3False;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3SetBoolean", nvr, nValues) != fmi3OK) return fmi3Error;
    if (nvr && (!vr || !values)) return (fmi3Status)inst_error(inst, 0, "fmi3SetBoolean: null array");
    for (size_t k = 0; k < nvr; k++) {
        int v = values[k] != fmi3False;
        int st = inst_set_bool(inst, &vr[k], 1, &v);
        if (st != STATUS_OK) return (fmi3Status)st;
    }
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3String values[],
                         size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3GetString", nvr, nValues) != fmi3OK) return fmi3Error;
    return (fmi3Status)inst_get_string(inst, vr, nvr, values);
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[],
                         size_t nValues) {
    CHECK(instance);
    if (scalars(inst, "fmi3SetString", nvr, nValues) != fmi3OK) return fmi3Error;
    return (fmi3Status)inst_set_string(inst, vr, nvr, values);
}

#define NO_VARIABLES(Name, T)                                                                                    \
    fmi3Status fmi3Get##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, T values[],      \
                             size_t nValues) {                                                                  \
        CHECK(instance);                                                                                        \
        (void)values, (void)nValues;                                                                            \
        if (nvr == 0) return fmi3OK;                                                                            \
        return (fmi3Status)inst_error(inst, 0, "fmi3Get" #Name ": value reference %u: no " #Name " variables", \
                                      vr ? vr[0] : 0u);                                                         \
    }                                                                                                           \
    fmi3Status fmi3Set##Name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const T values[], \
                             size_t nValues) {                                                                  \
        CHECK(instance);                                                                                        \
        (void)values, (void)nValues;                                                                            \
        if (nvr == 0) return fmi3OK;                                                                            \
        return (fmi3Status)inst_error(inst, 0, "fmi3Set" #Name ": value reference %u: no " #Name " variables", \
                                      vr ? vr[0] : 0u);                                                         \
    }

NO_VARIABLES(Float32, fmi3Float32)
NO_VARIABLES(Int8, fmi3Int8)
NO_VARIABLES(UInt8, fmi3UInt8)
NO_VARIABLES(Int16, fmi3Int16)
NO_VARIABLES(UInt16, fmi3UInt16)
NO_VARIABLES(Int32, fmi3Int32)
NO_VARIABLES(UInt32, fmi3UInt32)
NO_VARIABLES(Int64, fmi3Int64)
NO_VARIABLES(UInt64, fmi3UInt64)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    CHECK(instance);
    (void)valueSizes, (void)values, (void)nValues;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3GetBinary: value reference %u: no Binary variables", vr ? vr[0] : 0u);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    CHECK(instance);
    (void)valueSizes, (void)values, (void)nValues;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3SetBinary: value reference %u: no Binary variables", vr ? vr[0] : 0u);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    CHECK(instance);
    (void)values;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3GetClock: value reference %u: no clocks", vr ? vr[0] : 0u);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    CHECK(instance);
    (void)values;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3SetClock: value reference %u: no clocks", vr ? vr[0] : 0u);
}

#define UNSUPPORTED(call, ...)                                                         \
    {                                                                                  \
        CHECK(instance);                                                               \
        __VA_ARGS__;                                                                   \
        return (fmi3Status)inst_error(inst, 0, call ": not supported by this FMU");    \
    }

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies", (void)valueReference, (void)nDependencies)

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies)
    UNSUPPORTED("fmi3GetVariableDependencies", (void)dependent, (void)elementIndicesOfDependent, (void)independents,
                (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies)

/* ----------------------------------------------------------- FMU states */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(instance);
    return (fmi3Status)inst_get_state(inst, FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    CHECK(instance);
    return (fmi3Status)inst_set_state(inst, FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(instance);
    return (fmi3Status)inst_free_state(inst, FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    CHECK(instance);
    (void)FMUState;
    if (!size) return (fmi3Status)inst_error(inst, 0, "fmi3SerializedFMUStateSize: null pointer");
    *size = inst_state_size();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    CHECK(instance);
    return (fmi3Status)inst_serialize(inst, FMUState, (char *)serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    CHECK(instance);
    return (fmi3Status)inst_deserialize(inst, (const char *)serializedState, size, FMUState);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
    UNSUPPORTED("fmi3GetDirectionalDerivative", (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns,
                (void)seed, (void)nSeed, (void)sensitivity, (void)nSensitivity)

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
    UNSUPPORTED("fmi3GetAdjointDerivative", (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns,
                (void)seed, (void)nSeed, (void)sensitivity, (void)nSensitivity)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) UNSUPPORTED("fmi3EnterConfigurationMode", )
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) UNSUPPORTED("fmi3ExitConfigurationMode", )

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
    UNSUPPORTED("fmi3GetIntervalDecimal", (void)vr, (void)nvr, (void)intervals, (void)qualifiers)
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
    UNSUPPORTED("fmi3GetIntervalFraction", (void)vr, (void)nvr, (void)counters, (void)resolutions, (void)qualifiers)
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[])
    UNSUPPORTED("fmi3GetShiftDecimal", (void)vr, (void)nvr, (void)shifts)
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[])
    UNSUPPORTED("fmi3GetShiftFraction", (void)vr, (void)nvr, (void)counters, (void)resolutions)
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[])
    UNSUPPORTED("fmi3SetIntervalDecimal", (void)vr, (void)nvr, (void)intervals)
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
    UNSUPPORTED("fmi3SetIntervalFraction", (void)vr, (void)nvr, (void)counters, (void)resolutions)
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[])
    UNSUPPORTED("fmi3SetShiftDecimal", (void)vr, (void)nvr, (void)shifts)
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
    UNSUPPORTED("fmi3SetShiftFraction", (void)vr, (void)nvr, (void)counters, (void)resolutions)

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) UNSUPPORTED("fmi3EvaluateDiscreteStates", )

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
    UNSUPPORTED("fmi3UpdateDiscreteStates", (void)discreteStatesNeedUpdate, (void)terminateSimulation,
                (void)nominalsOfContinuousStatesChanged, (void)valuesOfContinuousStatesChanged,
                (void)nextEventTimeDefined, (void)nextEventTime)

/* ----------------------------------------------------------- model exchange: not provided */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) UNSUPPORTED("fmi3EnterContinuousTimeMode", )
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
    UNSUPPORTED("fmi3CompletedIntegratorStep", (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode,
                (void)terminateSimulation)
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) UNSUPPORTED("fmi3SetTime", (void)time)
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
    UNSUPPORTED("fmi3SetContinuousStates", (void)continuousStates, (void)nContinuousStates)
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
    UNSUPPORTED("fmi3GetContinuousStateDerivatives", (void)derivatives, (void)nContinuousStates)
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
    UNSUPPORTED("fmi3GetEventIndicators", (void)eventIndicators, (void)nEventIndicators)
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
    UNSUPPORTED("fmi3GetContinuousStates", (void)continuousStates, (void)nContinuousStates)
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates)
    UNSUPPORTED("fmi3GetNominalsOfContinuousStates", (void)nominals, (void)nContinuousStates)
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
    UNSUPPORTED("fmi3GetNumberOfEventIndicators", (void)nEventIndicators)
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
    UNSUPPORTED("fmi3GetNumberOfContinuousStates", (void)nContinuousStates)

/* ----------------------------------------------------------- co-simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    CHECK(instance);
    if (inst->s.state == ST_STEP) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3EnterStepMode: this FMU has no event mode");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    CHECK(instance);
    (void)vr, (void)orders, (void)values, (void)nValues;
    if (nvr == 0) return fmi3OK;
    return (fmi3Status)inst_error(inst, 0, "fmi3GetOutputDerivatives: not provided (maxOutputDerivativeOrder 0)");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    CHECK(instance);
    (void)noSetFMUStatePriorToCurrentPoint;
    int st = inst_do_step(inst, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = inst->s.time;
    return (fmi3Status)st;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
    UNSUPPORTED("fmi3ActivateModelPartition", (void)clockReference, (void)activationTime)
