/* A minimal non-Python FMI 3.0 co-simulation host, as C hosts are written: load the FMU's
 * binary, run one instance for 1 s in ten steps, free it and return from main without
 * dlclose (the library stays loaded until exit). Prints "RAN <value of vr_out>" or "REFUSED".
 * usage: plain_host3 <binary.so> <instantiation token> <resources folder> <vr_in> <value_in> <vr_out> */
#include <dlfcn.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

typedef void (*LogMessage)(void *env, int status, const char *category, const char *message);

static void log_message(void *env, int status, const char *category, const char *message)
{
    fprintf(stderr, "[%d %s] %s\n", status, category, message);
}

#define FN(type, name) \
    __typeof__(type) name = (__typeof__(type))dlsym(lib, #name); \
    if (!name) return 3;

int main(int argc, char **argv)
{
    if (argc != 7)
        return 2;
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 3;
    }
    FN(void *(*)(const char *, const char *, const char *, bool, bool, bool, bool,
                 const unsigned *, size_t, void *, LogMessage, void *),
       fmi3InstantiateCoSimulation)
    FN(int (*)(void *, bool, double, double, bool, double), fmi3EnterInitializationMode)
    FN(int (*)(void *), fmi3ExitInitializationMode)
    FN(int (*)(void *, const unsigned *, size_t, const double *, size_t), fmi3SetFloat64)
    FN(int (*)(void *, const unsigned *, size_t, double *, size_t), fmi3GetFloat64)
    FN(int (*)(void *, double, double, bool, bool *, bool *, bool *, double *), fmi3DoStep)
    FN(int (*)(void *), fmi3Terminate)
    FN(void (*)(void *), fmi3FreeInstance)
    void *c = fmi3InstantiateCoSimulation("host", argv[2], argv[3], false, true, false, false,
                                          NULL, 0, NULL, log_message, NULL);
    if (!c) {
        printf("REFUSED\n");
        return 0;
    }
    unsigned in = (unsigned)atoi(argv[4]), out = (unsigned)atoi(argv[6]);
    double value = atof(argv[5]), result = 0.0, last = 0.0;
    bool event, terminate, early;
    int status = fmi3EnterInitializationMode(c, false, 0.0, 0.0, true, 1.0);
    status |= fmi3ExitInitializationMode(c);
    status |= fmi3SetFloat64(c, &in, 1, &value, 1);
    for (int k = 0; k < 10; k++)
        status |= fmi3DoStep(c, k * 0.1, 0.1, true, &event, &terminate, &early, &last);
    status |= fmi3GetFloat64(c, &out, 1, &result, 1) | fmi3Terminate(c);
    fmi3FreeInstance(c);
    printf("RAN %.17g\n", result);
    return status;
}
