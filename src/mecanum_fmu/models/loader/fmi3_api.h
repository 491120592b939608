/* FMI 3.0 entry points of the loader (loader.c compiled with -DLOADER_FMI3): the types it
 * needs and the functions that jump to pythonfmu3's library (everything pythonfmu3 0.3.4
 * exports but fmi3GetVersion and the three fmi3Instantiate* functions, which are the loader's
 * own). Included by loader.c only. */
#include <stdbool.h>

typedef void (*fmi3LogMessageCallback)(void *instanceEnvironment, int status,
                                       const char *category, const char *message);
typedef void *(*instantiate_fn)(const char *, const char *, const char *, bool, bool, bool,
                                bool, const unsigned int *, size_t, void *,
                                fmi3LogMessageCallback, void *);

#define FORWARDED(X) \
    X(fmi3SetDebugLogging) X(fmi3FreeInstance) X(fmi3EnterInitializationMode) \
    X(fmi3ExitInitializationMode) X(fmi3EnterEventMode) X(fmi3Terminate) X(fmi3Reset) \
    X(fmi3GetFloat32) X(fmi3GetFloat64) X(fmi3GetInt8) X(fmi3GetUInt8) X(fmi3GetInt16) \
    X(fmi3GetUInt16) X(fmi3GetInt32) X(fmi3GetUInt32) X(fmi3GetInt64) X(fmi3GetUInt64) \
    X(fmi3GetBoolean) X(fmi3GetString) X(fmi3GetBinary) X(fmi3GetClock) \
    X(fmi3SetFloat32) X(fmi3SetFloat64) X(fmi3SetInt8) X(fmi3SetUInt8) X(fmi3SetInt16) \
    X(fmi3SetUInt16) X(fmi3SetInt32) X(fmi3SetUInt32) X(fmi3SetInt64) X(fmi3SetUInt64) \
    X(fmi3SetBoolean) X(fmi3SetString) X(fmi3SetBinary) X(fmi3SetClock) \
    X(fmi3GetNumberOfVariableDependencies) X(fmi3GetVariableDependencies) \
    X(fmi3GetFMUState) X(fmi3SetFMUState) X(fmi3FreeFMUState) X(fmi3SerializedFMUStateSize) \
    X(fmi3SerializeFMUState) X(fmi3DeserializeFMUState) X(fmi3GetDirectionalDerivative) \
    X(fmi3GetAdjointDerivative) X(fmi3EnterConfigurationMode) X(fmi3ExitConfigurationMode) \
    X(fmi3GetIntervalDecimal) X(fmi3GetIntervalFraction) X(fmi3GetShiftDecimal) \
    X(fmi3GetShiftFraction) X(fmi3SetIntervalDecimal) X(fmi3SetIntervalFraction) \
    X(fmi3SetShiftDecimal) X(fmi3SetShiftFraction) X(fmi3EvaluateDiscreteStates) \
    X(fmi3UpdateDiscreteStates) X(fmi3EnterContinuousTimeMode) X(fmi3CompletedIntegratorStep) \
    X(fmi3SetTime) X(fmi3SetContinuousStates) X(fmi3GetContinuousStateDerivatives) \
    X(fmi3GetEventIndicators) X(fmi3GetContinuousStates) X(fmi3GetNominalsOfContinuousStates) \
    X(fmi3GetNumberOfEventIndicators) X(fmi3GetNumberOfContinuousStates) X(fmi3EnterStepMode) \
    X(fmi3GetOutputDerivatives) X(fmi3DoStep) X(fmi3ActivateModelPartition)
#define INSTANTIATE "fmi3InstantiateCoSimulation"

EXPORT const char *fmi3GetVersion(void) { return "3.0"; }
