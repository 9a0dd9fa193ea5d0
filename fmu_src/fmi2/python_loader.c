/* python_loader.c: the binary of a pythonfmu FMU of papwc, that refuses with one line where
 * the host has no Python instead of crashing.
 *
 * A pythonfmu 0.7.0 binary runs the model in the Python of the host process and does not
 * link libpython itself: in a host with no Python loaded it fails to load, or crashes (ecos:
 * exit 139, no message). papwc's build puts pythonfmu's binary beside this one under another
 * name (LOADER_INNER, loader_config.h) and this one in its place. fmi2Instantiate looks for
 * a Python in the process (its Py_GetVersion: POSIX the process's symbols, Windows
 * python3.dll); with none, or one older than LOADER_PYTHON_MIN, it returns NULL and says
 * why in one line (to the host's logger and to stderr, unless PAPWC_FMU_STDERR=0); else it
 * loads pythonfmu's binary and every fmi2 function of the instance goes to it (in a host that
 * preloaded libpython and has not started Python, PYTHONHOME is set to that libpython's home
 * first, unless the host set it: see python_home). macOS has no
 * pythonfmu binary: there it always refuses, naming the native FMU.
 *
 * C99 (plus dladdr/dlopen or LoadLibrary); one allocation per instance, freed by
 * fmi2FreeInstance with the library reference it holds.
 */
#if !defined(_WIN32)
#define _GNU_SOURCE /* RTLD_DEFAULT, dladdr */
#endif

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(_WIN32)
#include <windows.h>
#else
#include <dlfcn.h>
#endif

#include "fmi2Functions.h"
#include "loader_config.h"

/* Every fmi2 function but the three this file answers itself. */
#define LOADER_FORWARDED(X) \
    X(fmi2SetDebugLogging) X(fmi2FreeInstance) X(fmi2SetupExperiment) \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate) \
    X(fmi2Reset) X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) X(fmi2GetFMUstate) \
    X(fmi2SetFMUstate) X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize) \
    X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative) \
    X(fmi2EnterEventMode) X(fmi2NewDiscreteStates) X(fmi2EnterContinuousTimeMode) \
    X(fmi2CompletedIntegratorStep) X(fmi2SetTime) X(fmi2SetContinuousStates) \
    X(fmi2GetDerivatives) X(fmi2GetEventIndicators) X(fmi2GetContinuousStates) \
    X(fmi2GetNominalsOfContinuousStates) X(fmi2SetRealInputDerivatives) \
    X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) X(fmi2CancelStep) X(fmi2GetStatus) \
    X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) X(fmi2GetBooleanStatus) \
    X(fmi2GetStringStatus)

typedef struct {
    void *library; /* pythonfmu's binary (a reference held by this instance) */
    fmi2Component inner;
#define X(name) name##TYPE *name;
    LOADER_FORWARDED(X)
#undef X
} Loader;

#define MESSAGE_LEN 1024

/* ---- the library and the Python of the process ------------------------------------------ */

#if defined(_WIN32)
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *symbol(void *library, const char *name)
{
    return (void *)GetProcAddress((HMODULE)library, name);
}
static void close_library(void *library) { FreeLibrary((HMODULE)library); }
static const char *load_error(void) { return "LoadLibrary failed"; }

/* The folder of this binary, with a trailing separator. */
static int own_folder(char *out, size_t len)
{
    HMODULE self = NULL;
    DWORD n;
    char *cut;
    if (!GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS |
                            GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCSTR)&own_folder, &self))
        return 1;
    n = GetModuleFileNameA(self, out, (DWORD)len);
    if (n == 0 || n >= len) return 1;
    cut = strrchr(out, '\\');
    if (cut == NULL) cut = strrchr(out, '/');
    if (cut == NULL) return 1;
    cut[1] = '\0';
    return 0;
}

static const char *python_version(void)
{
    HMODULE python = GetModuleHandleA("python3.dll");
    FARPROC get;
    if (python == NULL) python = LoadLibraryA("python3.dll");
    if (python == NULL) return NULL;
    get = GetProcAddress(python, "Py_GetVersion");
    return get != NULL ? ((const char *(*)(void))get)() : NULL;
}
#else
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(void *library, const char *name) { return dlsym(library, name); }
static void close_library(void *library) { dlclose(library); }
static const char *load_error(void)
{
    const char *why = dlerror();
    return why != NULL ? why : "dlopen failed";
}

static int own_folder(char *out, size_t len)
{
    Dl_info info;
    char *cut;
    if (dladdr((void *)&own_folder, &info) == 0 || info.dli_fname == NULL) return 1;
    if (strlen(info.dli_fname) >= len) return 1;
    strcpy(out, info.dli_fname);
    cut = strrchr(out, '/');
    if (cut == NULL) return 1;
    cut[1] = '\0';
    return 0;
}

static const char *python_version(void)
{
    void *get = dlsym(RTLD_DEFAULT, "Py_GetVersion");
    return get != NULL ? ((const char *(*)(void))get)() : NULL;
}

/* Python not yet started in a host that loaded libpython (LD_PRELOAD): the home of that
 * libpython, so that Python reads its own standard library, not that of another python3
 * first on PATH (which fails as "No module named 'math'"). PYTHONHOME set by the host is
 * kept. The home is the folder above the library's lib/ (or lib/<multiarch>/) that holds
 * lib/pythonX.Y/os.py. */
static void python_home(const char *version)
{
    void *started = dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    void *get = dlsym(RTLD_DEFAULT, "Py_GetVersion");
    char home[4096], probe[4200], *cut;
    FILE *os_py;
    int major = 0, minor = 0, up;
    Dl_info info;
    if (getenv("PYTHONHOME") != NULL || started == NULL || ((int (*)(void))started)() != 0)
        return;
    if (get == NULL || dladdr(get, &info) == 0 || info.dli_fname == NULL ||
        strlen(info.dli_fname) >= sizeof home || sscanf(version, "%d.%d", &major, &minor) != 2)
        return;
    strcpy(home, info.dli_fname);
    for (up = 0; up < 3; up++) {
        cut = strrchr(home, '/');
        if (cut == NULL || cut == home) return;
        *cut = '\0';
        snprintf(probe, sizeof probe, "%s/lib/python%d.%d/os.py", home, major, minor);
        os_py = fopen(probe, "r");
        if (os_py != NULL) {
            fclose(os_py);
            setenv("PYTHONHOME", home, 0);
            return;
        }
    }
}
#endif

/* ---- refusing ------------------------------------------------------------------------------ */

static int stderr_wanted(void)
{
    const char *flag = getenv("PAPWC_FMU_STDERR");
    return !(flag != NULL && strcmp(flag, "0") == 0);
}

/* The one line that says why there is no instance: to the logger and to stderr. */
static void refuse(const fmi2CallbackFunctions *functions, fmi2String name, const char *why)
{
    char line[MESSAGE_LEN], escaped[2 * MESSAGE_LEN];
    size_t i, j = 0;
    snprintf(line, sizeof line, "%s: fmi2Instantiate refused: %s", name, why);
    for (i = 0; line[i] != '\0' && j + 2 < sizeof escaped; i++) { /* a logger formats it */
        if (line[i] == '%') escaped[j++] = '%';
        escaped[j++] = line[i];
    }
    escaped[j] = '\0';
    if (functions != NULL && functions->logger != NULL)
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          escaped);
    if (stderr_wanted()) {
        fprintf(stderr, "%s %s\n", LOADER_MODEL, line);
        fflush(stderr);
    }
}

/* Whether version ("3.11.7 (main, ...)") is at least LOADER_PYTHON_MIN. */
static int recent_enough(const char *version)
{
    int major = 0, minor = 0;
    if (sscanf(version, "%d.%d", &major, &minor) != 2) return 0;
    return major > LOADER_PYTHON_MAJOR ||
           (major == LOADER_PYTHON_MAJOR && minor >= LOADER_PYTHON_MINOR);
}

#define NO_PYTHON_HELP \
    " (Linux: start the host with LD_PRELOAD=<libpython3.X.so.1.0>, the line `papwc " \
    "hostenv` prints; Windows: a 64-bit Python's folder on PATH). The kinds pwc, papwc and " \
    "pid need no Python: the native PulseController.fmu (papwc build) runs them"

/* ---- the functions ----------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    char why[MESSAGE_LEN], path[4096];
    const char *name = instanceName != NULL ? instanceName : "";
    const char *version;
    Loader *loader;
    void *library;
    fmi2Component inner;
#if defined(__APPLE__)
    (void)version; (void)loader; (void)library; (void)inner; (void)path;
    (void)fmuType; (void)fmuGUID; (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    snprintf(why, sizeof why, LOADER_MODEL ".fmu is a pythonfmu FMU and pythonfmu 0.7.0 "
             "has no macOS binary. The kinds pwc, papwc and pid need no Python: the native "
             "PulseController.fmu (papwc build) runs them on macOS");
    refuse(functions, name, why);
    return NULL;
#else
    version = python_version();
    if (version == NULL) {
        snprintf(why, sizeof why, LOADER_MODEL ".fmu runs its model in the host's Python "
                 "%d.%d or newer, and this process has no Python loaded" NO_PYTHON_HELP,
                 LOADER_PYTHON_MAJOR, LOADER_PYTHON_MINOR);
        refuse(functions, name, why);
        return NULL;
    }
    if (!recent_enough(version)) {
        snprintf(why, sizeof why, LOADER_MODEL ".fmu needs Python %d.%d or newer in the "
                 "host; this process runs Python %.16s" NO_PYTHON_HELP, LOADER_PYTHON_MAJOR,
                 LOADER_PYTHON_MINOR, version);
        refuse(functions, name, why);
        return NULL;
    }
#if !defined(_WIN32)
    python_home(version);
#endif
    if (own_folder(path, sizeof path - sizeof LOADER_INNER) != 0) {
        refuse(functions, name, "the folder of " LOADER_MODEL "'s binary is not known");
        return NULL;
    }
    strcat(path, LOADER_INNER);
    library = open_library(path);
    if (library == NULL) {
        snprintf(why, sizeof why, "pythonfmu's binary %.1000s cannot be loaded: %.500s", path,
                 load_error());
        refuse(functions, name, why);
        return NULL;
    }
    loader = (Loader *)calloc(1, sizeof(Loader));
    if (loader == NULL) {
        close_library(library);
        return NULL;
    }
    loader->library = library;
#define X(fn) loader->fn = (fn##TYPE *)symbol(library, #fn);
    LOADER_FORWARDED(X) /* a function pythonfmu lacks (Model Exchange) answers fmi2Error */
#undef X
    if (loader->fmi2FreeInstance == NULL) {
        close_library(library);
        free(loader);
        refuse(functions, name, "pythonfmu's binary exports no fmi2FreeInstance");
        return NULL;
    }
    {
        fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)symbol(library,
                                                                         "fmi2Instantiate");
        inner = instantiate != NULL ? instantiate(instanceName, fmuType, fmuGUID,
                                                  fmuResourceLocation, functions, visible,
                                                  loggingOn) : NULL;
    }
    if (inner == NULL) { /* pythonfmu has said why */
        close_library(library);
        free(loader);
        return NULL;
    }
    loader->inner = inner;
    return loader;
#endif
}

void fmi2FreeInstance(fmi2Component c)
{
    Loader *loader = (Loader *)c;
    if (loader == NULL) return;
    loader->fmi2FreeInstance(loader->inner);
    close_library(loader->library);
    free(loader);
}

/* A forwarded function: the instance's call of pythonfmu's, with its own component
 * (fmi2Error where pythonfmu's binary has no such function). */
#define FORWARD(name, params, args) \
    fmi2Status name params { \
        Loader *loader = (Loader *)c; \
        if (loader == NULL || loader->name == NULL) return fmi2Error; \
        return loader->name args; \
    }

FORWARD(fmi2SetDebugLogging, (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String k[]),
        (loader->inner, on, n, k))
FORWARD(fmi2SetupExperiment, (fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0,
                              fmi2Boolean sd, fmi2Real t1), (loader->inner, td, tol, t0, sd, t1))
FORWARD(fmi2EnterInitializationMode, (fmi2Component c), (loader->inner))
FORWARD(fmi2ExitInitializationMode, (fmi2Component c), (loader->inner))
FORWARD(fmi2Terminate, (fmi2Component c), (loader->inner))
FORWARD(fmi2Reset, (fmi2Component c), (loader->inner))
#define FORWARD_VALUES(name, type) \
    FORWARD(name, (fmi2Component c, const fmi2ValueReference vr[], size_t n, type v[]), \
            (loader->inner, vr, n, v))
FORWARD_VALUES(fmi2GetReal, fmi2Real)
FORWARD_VALUES(fmi2GetInteger, fmi2Integer)
FORWARD_VALUES(fmi2GetBoolean, fmi2Boolean)
FORWARD_VALUES(fmi2GetString, fmi2String)
FORWARD_VALUES(fmi2SetReal, const fmi2Real)
FORWARD_VALUES(fmi2SetInteger, const fmi2Integer)
FORWARD_VALUES(fmi2SetBoolean, const fmi2Boolean)
FORWARD_VALUES(fmi2SetString, const fmi2String)
FORWARD(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *s), (loader->inner, s))
FORWARD(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate s), (loader->inner, s))
FORWARD(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *s), (loader->inner, s))
FORWARD(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate s, size_t *n),
        (loader->inner, s, n))
FORWARD(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n),
        (loader->inner, s, b, n))
FORWARD(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte b[], size_t n,
                                  fmi2FMUstate *s), (loader->inner, b, n, s))
FORWARD(fmi2GetDirectionalDerivative, (fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                       const fmi2ValueReference k[], size_t nk,
                                       const fmi2Real dk[], fmi2Real du[]),
        (loader->inner, u, nu, k, nk, dk, du))
FORWARD(fmi2EnterEventMode, (fmi2Component c), (loader->inner))
FORWARD(fmi2NewDiscreteStates, (fmi2Component c, fmi2EventInfo *e), (loader->inner, e))
FORWARD(fmi2EnterContinuousTimeMode, (fmi2Component c), (loader->inner))
FORWARD(fmi2CompletedIntegratorStep, (fmi2Component c, fmi2Boolean p, fmi2Boolean *e,
                                      fmi2Boolean *t), (loader->inner, p, e, t))
FORWARD(fmi2SetTime, (fmi2Component c, fmi2Real t), (loader->inner, t))
FORWARD(fmi2SetContinuousStates, (fmi2Component c, const fmi2Real x[], size_t n),
        (loader->inner, x, n))
FORWARD(fmi2GetDerivatives, (fmi2Component c, fmi2Real x[], size_t n), (loader->inner, x, n))
FORWARD(fmi2GetEventIndicators, (fmi2Component c, fmi2Real x[], size_t n),
        (loader->inner, x, n))
FORWARD(fmi2GetContinuousStates, (fmi2Component c, fmi2Real x[], size_t n),
        (loader->inner, x, n))
FORWARD(fmi2GetNominalsOfContinuousStates, (fmi2Component c, fmi2Real x[], size_t n),
        (loader->inner, x, n))
FORWARD(fmi2SetRealInputDerivatives, (fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      const fmi2Integer o[], const fmi2Real v[]),
        (loader->inner, vr, n, o, v))
FORWARD(fmi2GetRealOutputDerivatives, (fmi2Component c, const fmi2ValueReference vr[],
                                       size_t n, const fmi2Integer o[], fmi2Real v[]),
        (loader->inner, vr, n, o, v))
FORWARD(fmi2DoStep, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean p),
        (loader->inner, t, h, p))
FORWARD(fmi2CancelStep, (fmi2Component c), (loader->inner))
FORWARD(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Status *v),
        (loader->inner, k, v))
FORWARD(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Real *v),
        (loader->inner, k, v))
FORWARD(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Integer *v),
        (loader->inner, k, v))
FORWARD(fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v),
        (loader->inner, k, v))
FORWARD(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind k, fmi2String *v),
        (loader->inner, k, v))
