/* fmi3InstantiateCoSimulation of the FMI 3.0 loader (loader.c with -DLOADER_FMI3): Python and
 * pythonfmu3's library loaded on the first call, as fmi2Instantiate does in the FMI 2.0 one.
 * The FMU is co-simulation only: the other two kinds return NULL, as FMI 3.0 asks. */
/* libffi, which the bundled Python's _ctypes needs (pythonfmu3 imports ctypes): the host's
 * when it has one loaded, else the FMU's own copy, loaded global so that _ctypes finds it. */
static void load_libffi(void)
{
    char lib[4096];
    if (dlopen("libffi.so.8", RTLD_NOW | RTLD_GLOBAL | RTLD_NOLOAD))
        return;
    snprintf(lib, sizeof lib, "%s/libffi.so.8", binaries);
    dlopen(lib, RTLD_NOW | RTLD_GLOBAL);   /* missing: pythonfmu3 reports the failed import */
}

EXPORT void *fmi3InstantiateCoSimulation(const char *name, const char *token,
                                         const char *resources, bool visible, bool logging,
                                         bool event_mode, bool early_return,
                                         const unsigned int *required, size_t n_required,
                                         void *environment, fmi3LogMessageCallback log_message,
                                         void *intermediate_update)
{
    pthread_mutex_lock(&lock);
    if (!real_instantiate && !message[0]) {
        load_libffi();
        load();
    }
    instantiate_fn real = real_instantiate;
    pthread_mutex_unlock(&lock);
    if (real)
        return real(name, token, resources, visible, logging, event_mode, early_return,
                    required, n_required, environment, log_message, intermediate_update);
    if (log_message)        /* FMI 3.0 passes the message as text, not as a format */
        log_message(environment, 3 /* fmi3Error */, "logStatusError", message);
    return NULL;
}

EXPORT void *fmi3InstantiateModelExchange(const char *name, const char *token,
                                          const char *resources, bool visible, bool logging,
                                          void *environment, fmi3LogMessageCallback log_message)
{
    return NULL;
}

EXPORT void *fmi3InstantiateScheduledExecution(const char *name, const char *token,
                                               const char *resources, bool visible,
                                               bool logging, void *environment,
                                               fmi3LogMessageCallback log_message,
                                               void *clock_update, void *lock_preemption,
                                               void *unlock_preemption)
{
    return NULL;
}
