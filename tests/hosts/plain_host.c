/* A minimal non-Python FMI 2.0 co-simulation host, as C hosts are written: load the FMU's
 * binary, run one instance for 1 s, free it and return from main without dlclose (the library
 * stays loaded until exit). Prints "RAN <value of vr_out>" or "REFUSED".
 * usage: plain_host <binary.so> <guid> <resources URI> <vr_in> <value_in> <vr_out> */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, int);
    void *componentEnvironment;
} Callbacks;

static void logger(void *env, const char *name, int status, const char *category,
                   const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fprintf(stderr, "[%s %d %s] ", name, status, category);
    vfprintf(stderr, format, args);
    fputc('\n', stderr);
    va_end(args);
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
    FN(void *(*)(const char *, int, const char *, const char *, const Callbacks *, int, int),
       fmi2Instantiate)
    FN(int (*)(void *, int, double, double, int, double), fmi2SetupExperiment)
    FN(int (*)(void *), fmi2EnterInitializationMode)
    FN(int (*)(void *), fmi2ExitInitializationMode)
    FN(int (*)(void *, const unsigned *, size_t, const double *), fmi2SetReal)
    FN(int (*)(void *, const unsigned *, size_t, double *), fmi2GetReal)
    FN(int (*)(void *, double, double, int), fmi2DoStep)
    FN(int (*)(void *), fmi2Terminate)
    FN(void (*)(void *), fmi2FreeInstance)
    Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    void *c = fmi2Instantiate("host", 1, argv[2], argv[3], &callbacks, 0, 0);
    if (!c) {
        printf("REFUSED\n");
        return 0;
    }
    unsigned in = (unsigned)atoi(argv[4]), out = (unsigned)atoi(argv[6]);
    double value = atof(argv[5]), result = 0.0;
    int status = fmi2SetupExperiment(c, 0, 0.0, 0.0, 1, 1.0);
    status |= fmi2EnterInitializationMode(c) | fmi2ExitInitializationMode(c);
    status |= fmi2SetReal(c, &in, 1, &value);
    for (int k = 0; k < 10; k++)
        status |= fmi2DoStep(c, k * 0.1, 0.1, 1);
    status |= fmi2GetReal(c, &out, 1, &result) | fmi2Terminate(c);
    fmi2FreeInstance(c);
    printf("RAN %.17g\n", result);
    return status;
}
