/* The binary an FMI host loads (binaries/linux64/<Model>.so): a small loader in front of
 * pythonfmu's export library, so the FMU carries the Python it needs (built by
 * mecanum_fmu/models/runtime.py at `make fmus`; compiled against the bundled Python's headers).
 *
 * When the host loads this file (a constructor: under the dynamic loader's lock):
 *   - a Python already in the process (dlsym(RTLD_DEFAULT, "Py_GetVersion")) of the bundled
 *     major.minor version: that interpreter is used (a Python host such as fmpy);
 *   - a Python of another version: a clear message through the host's logger, NULL returned
 *     (never two interpreters in one process);
 *   - no Python: the bundled libpython (next to this file) is loaded RTLD_GLOBAL and started
 *     isolated: stdlib from the FMU's resources/python/ only, no site, no environment
 *     variables, no signal handlers.
 * Before either, the bundled files it will open (in a host's own Python: pythonfmu's library
 * alone) are checked against the size and SHA-256 the build recorded in
 * resources/python/MANIFEST (bundle_check.h): a damaged FMU opens none of them, and
 * fmi2Instantiate returns NULL with one message naming the file.
 * On the first fmi2Instantiate, pythonfmu's library (<Model>.pythonfmu.so, next to this file) is loaded and every fmi2
 * function jumps to it (signature-free trampolines, x86_64).
 * Compiled with -DLOADER_FMI3 it is the same loader for pythonfmu3's FMI 3.0 library: its entry
 * points are in fmi3_api.h and fmi3_instantiate.h, everything else is shared.
 */
#define _GNU_SOURCE
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bundle_check.h"

/* Bind the dl* calls to their oldest symbol versions: the glibc floor stays pythonfmu's. */
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");

#define REAL_SUFFIX ".pythonfmu.so"     /* <Model>.so -> <Model>.pythonfmu.so */
#define MARKER "_mecanum_fmu_runtime"    /* sys attribute: an interpreter this loader started */
#define EXPORT __attribute__((visibility("default")))
#define MANIFEST "resources/python/MANIFEST"   /* models/embed.py writes it */
#ifdef LOADER_FMI3
#define PLATFORM_DIR "binaries/x86_64-linux/"   /* FMI 3.0's platform folder */
#else
#define PLATFORM_DIR "binaries/linux64/"
#endif

#ifdef LOADER_FMI3
#include "fmi3_api.h"
#else
typedef void (*fmi2Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    fmi2Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, int);
    void *componentEnvironment;
} fmi2CallbackFunctions;
typedef void *(*instantiate_fn)(const char *, int, const char *, const char *,
                                const fmi2CallbackFunctions *, int, int);

#define FORWARDED(X) \
    X(fmi2SetDebugLogging) X(fmi2FreeInstance) X(fmi2SetupExperiment) \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate) \
    X(fmi2Reset) X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) \
    X(fmi2GetFMUstate) X(fmi2SetFMUstate) X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize) \
    X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative) \
    X(fmi2SetRealInputDerivatives) X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) \
    X(fmi2CancelStep) X(fmi2GetStatus) X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) \
    X(fmi2GetBooleanStatus) X(fmi2GetStringStatus)
#define INSTANTIATE "fmi2Instantiate"
#endif

/* Until pythonfmu's library is loaded, every call fails with fmi2Error: a host that goes on
 * after fmi2Instantiate returned NULL (Ecos' `ecos` does) gets an error, not a jump to NULL.
 * Every forwarded function returns an fmi2Status but fmi2FreeInstance, which ignores it. */
static int refused_call(void)
{
    return 3;                       /* fmi2Error */
}

/* A jump through real_<name>, set once pythonfmu's library is loaded. */
#define TRAMPOLINE(name) \
    __attribute__((visibility("hidden"))) void *real_##name = (void *)refused_call; \
    __asm__(".text\n.globl " #name "\n.type " #name ",@function\n" #name ":\n" \
            "\tjmp *real_" #name "(%rip)\n.size " #name ",.-" #name "\n");
FORWARDED(TRAMPOLINE)

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static instantiate_fn real_instantiate;
static char message[1024];          /* why loading failed (kept: every later call says it) */
static char binaries[4096], model[1024];    /* this file's folder and model name */

#ifndef LOADER_FMI3
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }
#endif

static int fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    return -1;
}

/* The folder holding this file (binaries/linux64, no trailing slash) and its model name. */
static int own_place(char *folder, size_t size, char *name, size_t name_size)
{
    Dl_info info;
    if (!dladdr((void *)&own_place, &info) || !info.dli_fname)
        return fail("cannot find the FMU's own binary (dladdr)");
    snprintf(folder, size, "%s", info.dli_fname);
    char *slash = strrchr(folder, '/');
    if (!slash)
        return fail("the FMU's binary path %s has no folder", folder);
    *slash = '\0';
    snprintf(name, name_size, "%s", slash + 1);
    char *dot = strrchr(name, '.');
    if (dot)
        *dot = '\0';
    return 0;
}

#define SYM(handle, name) \
    __typeof__(&name) p_##name = (__typeof__(&name))dlsym(handle, #name); \
    if (!p_##name) return fail("%s not found in the Python library", #name);

/* Start the interpreter of `handle`: isolated, its stdlib from resources/python only. */
static int start_python(void *handle, const char *folder)
{
    SYM(handle, PyConfig_InitIsolatedConfig) SYM(handle, PyConfig_SetBytesString)
    SYM(handle, PyWideStringList_Append) SYM(handle, Py_DecodeLocale)
    SYM(handle, Py_InitializeFromConfig) SYM(handle, PyConfig_Clear)
    SYM(handle, PyStatus_Exception) SYM(handle, PyEval_SaveThread) SYM(handle, PyMem_RawFree)
    SYM(handle, PyPreConfig_InitIsolatedConfig) SYM(handle, Py_PreInitialize)
    char home[4096], path[4096];
    snprintf(home, sizeof home, "%s/../../resources/python", folder);
    PyPreConfig pre;                /* UTF-8 mode: no locale codec to find in the stdlib */
    p_PyPreConfig_InitIsolatedConfig(&pre);
    pre.utf8_mode = 1;
    PyStatus status = p_Py_PreInitialize(&pre);
    if (p_PyStatus_Exception(status))
        return fail("the FMU %s: its bundled Python did not start: %s", model,
                    status.err_msg ? status.err_msg : "?");
    PyConfig config;
    p_PyConfig_InitIsolatedConfig(&config);
    config.site_import = 0;
    config.install_signal_handlers = 0;
    config.write_bytecode = 0;
    config.pathconfig_warnings = 0;
    config.module_search_paths_set = 1;
    const char *entries[] = {"stdlib.zip", "lib-dynload"};
    status = p_PyConfig_SetBytesString(&config, &config.home, home);
    for (int i = 0; i < 2 && !p_PyStatus_Exception(status); i++) {
        snprintf(path, sizeof path, "%s/%s", home, entries[i]);
        wchar_t *wide = p_Py_DecodeLocale(path, NULL);
        status = p_PyWideStringList_Append(&config.module_search_paths, wide);
        p_PyMem_RawFree(wide);
    }
    if (!p_PyStatus_Exception(status))
        status = p_Py_InitializeFromConfig(&config);
    p_PyConfig_Clear(&config);
    if (p_PyStatus_Exception(status))
        return fail("the FMU %s: its bundled Python did not start: %s", model,
                    status.err_msg ? status.err_msg : "?");
    SYM(handle, PySys_SetObject) SYM(handle, PyUnicode_DecodeFSDefault) SYM(handle, Py_DecRef)
    PyObject *marker = p_PyUnicode_DecodeFSDefault(home);
    p_PySys_SetObject(MARKER, marker);
    p_Py_DecRef(marker);
    p_PyEval_SaveThread();          /* release the GIL: pythonfmu takes it per call */
    return 0;
}

/* The Python this process will use: the one already there, else the bundled one. */
static void *python;

static int find_python(const char *folder)
{
    /* A libpython of our version loaded by someone else (another of our FMUs), even RTLD_LOCAL:
     * found by its soname, promoted to the global scope. */
    void *loaded = dlopen(BUNDLED_LIBPYTHON, RTLD_NOW | RTLD_GLOBAL | RTLD_NOLOAD);
    const char *(*version)(void) = (const char *(*)(void))dlsym(RTLD_DEFAULT, "Py_GetVersion");
    void *handle = RTLD_DEFAULT;
    if (version) {
        const char *v = version();
        char want[16];
        snprintf(want, sizeof want, "%d.%d.", PY_MAJOR_VERSION, PY_MINOR_VERSION);
        if (strncmp(v, want, strlen(want)) != 0)
            return fail("this FMU bundles Python %d.%d, but the process already runs Python "
                        "%.*s; two interpreters cannot share a process. Load it in a host "
                        "without Python or with Python %d.%d (e.g. the `ecos` program, or "
                        "fmpy on Python %d.%d)", PY_MAJOR_VERSION, PY_MINOR_VERSION,
                        (int)strcspn(v, " "), v,
                        PY_MAJOR_VERSION, PY_MINOR_VERSION, PY_MAJOR_VERSION, PY_MINOR_VERSION);
    } else if (loaded) {
        handle = loaded;
    } else {
        char lib[4096];
        snprintf(lib, sizeof lib, "%s/%s", folder, BUNDLED_LIBPYTHON);
        handle = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
        if (!handle)
            return fail("cannot load the bundled Python: %s", dlerror());
    }
    python = handle;
    int (*initialized)(void) = (int (*)(void))dlsym(handle, "Py_IsInitialized");
    if (initialized && initialized())
        return 0;
    return start_python(handle, folder);
}

/* In an interpreter a loader started (another FMU's, maybe with other stdlib modules), put
 * this FMU's stdlib on sys.path too. A host's own interpreter is left as it is. */
static int add_paths(void *handle, const char *folder)
{
    SYM(handle, PyGILState_Ensure) SYM(handle, PyGILState_Release) SYM(handle, PySys_GetObject)
    SYM(handle, PyUnicode_DecodeFSDefault) SYM(handle, PyList_Append) SYM(handle, Py_DecRef)
    SYM(handle, PySequence_Contains) SYM(handle, PyErr_Clear)
    const char *entries[] = {"stdlib.zip", "lib-dynload"};
    char path[4096];
    PyGILState_STATE gil = p_PyGILState_Ensure();
    PyObject *sys_path = p_PySys_GetObject("path");
    for (int i = 0; i < 2 && p_PySys_GetObject(MARKER) && sys_path; i++) {
        snprintf(path, sizeof path, "%s/../../resources/python/%s", folder, entries[i]);
        PyObject *item = p_PyUnicode_DecodeFSDefault(path);
        if (item && p_PySequence_Contains(sys_path, item) == 0)
            p_PyList_Append(sys_path, item);
        if (item)
            p_Py_DecRef(item);
    }
    p_PyErr_Clear();
    p_PyGILState_Release(gil);
    return 0;
}

/* pythonfmu 0.7.0 keeps its interpreter state in a static std::shared_ptr and resets it in a
 * destructor function (finalizePythonInterpreter). For a library nobody dlcloses (this loader
 * never closes it), exit() destroys the shared_ptr first and calls that function after it, on
 * freed memory: glibc aborts the host now and then ("corrupted double-linked list", valgrind:
 * an invalid read in finalizePythonInterpreter). An exit handler registered once pythonfmu's
 * library is loaded runs before its static destructors, so the state is reset while it lives.
 * pythonfmu never finalizes an interpreter it did not start, and it starts none here. */
static void (*release_state)(void);

static void release_at_exit(void)
{
    release_state();
}

static int load_real(const char *folder, const char *identifier)
{
    char lib[4096];
    snprintf(lib, sizeof lib, "%s/%s" REAL_SUFFIX, folder, identifier);
    void *handle = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
    if (!handle)
        return fail("cannot load pythonfmu's library: %s", dlerror());
#define PRESENT(name) \
    if (!dlsym(handle, #name)) return fail("%s missing in %s", #name, lib);
#define RESOLVE(name) real_##name = dlsym(handle, #name);
    FORWARDED(PRESENT)              /* all or none: a trampoline never jumps to NULL */
    FORWARDED(RESOLVE)
    real_instantiate = (instantiate_fn)dlsym(handle, INSTANTIATE);
    if (!real_instantiate)
        return fail(INSTANTIATE " missing in %s", lib);
    release_state = (void (*)(void))dlsym(handle, "finalizePythonInterpreter");
    if (release_state)
        atexit(release_at_exit);
    return 0;
}

/* Whether this process runs its own Python (not one a loader of ours started from an FMU's
 * bundled libpython, which sits next to that FMU's MANIFEST): then only pythonfmu's library of
 * this FMU gets opened. */
static int host_python(void)
{
    void *version = dlsym(RTLD_DEFAULT, "Py_GetVersion");
    Dl_info info;
    if (!version || !dladdr(version, &info) || !info.dli_fname)
        return 0;
    char list[4200];
    snprintf(list, sizeof list, "%s", info.dli_fname);
    char *slash = strrchr(list, '/');
    if (!slash)
        return 1;
    snprintf(slash, sizeof list - (size_t)(slash - list), "/../../%s", MANIFEST);
    return access(list, F_OK) != 0;
}

/* The bundled files this process will open, as the build recorded them; else a message naming
 * the first damaged one. */
static int check_files(void)
{
    char root[4200], why[sizeof message - 200], real[1100];
    snprintf(root, sizeof root, "%s/../..", binaries);
    snprintf(real, sizeof real, PLATFORM_DIR "%s" REAL_SUFFIX, model);
    if (bundle_check(root, MANIFEST, host_python() ? real : NULL, why, sizeof why) == 0)
        return 0;
    return fail("the FMU %s is damaged: %s; nothing of it was loaded. Unpack it again or "
                "rebuild it (python -m mecanum_fmu fmus)", model, why);
}

/* Runs when the host loads this file, under the dynamic loader's lock: two FMUs loaded at once
 * by two threads cannot both find no Python and start one each. */
__attribute__((constructor)) static void at_load(void)
{
    if (own_place(binaries, sizeof binaries, model, sizeof model) == 0 && check_files() == 0)
        find_python(binaries);
}

static int load(void)
{
    if (add_paths(python, binaries))
        return -1;
    return load_real(binaries, model);
}

#ifdef LOADER_FMI3
#include "fmi3_instantiate.h"
#else
EXPORT void *fmi2Instantiate(const char *name, int type, const char *guid, const char *resources,
                             const fmi2CallbackFunctions *functions, int visible, int logging)
{
    pthread_mutex_lock(&lock);
    if (!real_instantiate && !message[0])
        load();
    instantiate_fn real = real_instantiate;
    pthread_mutex_unlock(&lock);
    if (real)
        return real(name, type, guid, resources, functions, visible, logging);
    if (functions && functions->logger) {
        /* the message as the format itself ('%' doubled): hosts that print the format
         * without formatting it (some do) show the text too */
        char format[2 * sizeof message];
        size_t j = 0;
        for (size_t i = 0; message[i] && j + 2 < sizeof format; i++) {
            if (message[i] == '%')
                format[j++] = '%';
            format[j++] = message[i];
        }
        format[j] = '\0';
        functions->logger(functions->componentEnvironment, name, 3 /* fmi2Error */,
                          "logStatusError", format);
    }
    return NULL;
}
#endif
