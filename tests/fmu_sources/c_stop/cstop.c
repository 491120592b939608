/* Test FMU (FMI 2.0 co-simulation, plain C): y = t, that asks to end the simulation on the
 * step that reaches t_end, as the Reference FMUs' Stair does at 9 s: fmi2DoStep returns
 * fmi2Discard and fmi2GetBooleanStatus(fmi2Terminated) true. With short = 1 that step stops
 * at its start (fmi2LastSuccessfulTime), with short = 0 it gets to its end.
 * Built by tests/test_fmu_ends_run.py; the rest of FMI 2.0 is present and minimal. */
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

typedef struct { double time, last, t_end; int shorten, terminated; } Stop;

#define ME(c) ((Stop *)(c))
#define UNSUPPORTED(name, ...) fmi2Status name(__VA_ARGS__) { return fmi2Error; }

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String n, fmi2Type t, fmi2String g, fmi2String r,
                              const fmi2CallbackFunctions *f, fmi2Boolean v, fmi2Boolean l) {
    Stop *s = calloc(1, sizeof(Stop));
    if (s) s->t_end = 1.0;
    return s;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n, const fmi2String k[]) {
    return fmi2OK;
}
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                               fmi2Boolean sd, fmi2Real stop) {
    ME(c)->time = ME(c)->last = start;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    double t_end = ME(c)->t_end;
    memset(c, 0, sizeof(Stop));
    ME(c)->t_end = t_end;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 0) v[i] = ME(c)->time;
        else if (vr[i] == 1) v[i] = ME(c)->t_end;
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 1) ME(c)->t_end = v[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 2) v[i] = ME(c)->shorten;
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 2) ME(c)->shorten = v[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noPrior) {
    Stop *s = ME(c);
    if (s->terminated) return fmi2Error;
    if (t + h >= s->t_end - 1e-9 * h) {
        s->terminated = 1;
        s->last = s->time = s->shorten ? t : t + h;
        return fmi2Discard;
    }
    s->last = s->time = t + h;
    return fmi2OK;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    if (k != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ME(c)->last;
    return fmi2OK;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) {
    if (k != fmi2Terminated) return fmi2Discard;
    *v = ME(c)->terminated;
    return fmi2OK;
}

UNSUPPORTED(fmi2GetFMUstate, fmi2Component c, fmi2FMUstate *s)
UNSUPPORTED(fmi2SetFMUstate, fmi2Component c, fmi2FMUstate s)
UNSUPPORTED(fmi2FreeFMUstate, fmi2Component c, fmi2FMUstate *s)
UNSUPPORTED(fmi2SerializedFMUstateSize, fmi2Component c, fmi2FMUstate s, size_t *n)
UNSUPPORTED(fmi2SerializeFMUstate, fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
UNSUPPORTED(fmi2DeSerializeFMUstate, fmi2Component c, const fmi2Byte b[], size_t n,
            fmi2FMUstate *s)
UNSUPPORTED(fmi2GetDirectionalDerivative, fmi2Component c, const fmi2ValueReference u[],
            size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
            fmi2Real dz[])
UNSUPPORTED(fmi2SetRealInputDerivatives, fmi2Component c, const fmi2ValueReference vr[],
            size_t n, const fmi2Integer o[], const fmi2Real v[])
UNSUPPORTED(fmi2GetRealOutputDerivatives, fmi2Component c, const fmi2ValueReference vr[],
            size_t n, const fmi2Integer o[], fmi2Real v[])
UNSUPPORTED(fmi2CancelStep, fmi2Component c)
UNSUPPORTED(fmi2GetStatus, fmi2Component c, const fmi2StatusKind k, fmi2Status *v)
UNSUPPORTED(fmi2GetIntegerStatus, fmi2Component c, const fmi2StatusKind k, fmi2Integer *v)
UNSUPPORTED(fmi2GetStringStatus, fmi2Component c, const fmi2StatusKind k, fmi2String *v)
