/* fmu_host.c: a minimal FMI 2.0 Co-Simulation host in C, with no Python anywhere.
 *
 *   fmu_host BINARY GUID T [r|i|b:VR=VALUE ...] -- OUT_VR[r|i] ...   < readings
 *
 * loads the FMU's binary (dlopen), instantiates it (its resources: the folder resources/ of
 * the extracted FMU BINARY lies in, as a file:// URI), sets the parameters given (Real, Integer
 * or Boolean, by value reference), initializes, then for each line "x_meas_vr x_meas
 * [more vr value pairs]" of stdin sets those inputs, calls fmi2DoStep(t, T) and prints the
 * outputs asked for (a Real as C's %a: its exact bits; an Integer as %d), one line per
 * step. The exit status is 0, or 3 after the first call that does not return fmi2OK (its
 * status and the log are on stderr). tests/integration/test_native_controller_fmu.py runs
 * PulseController.fmu in it.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    va_list args;
    (void)env;
    fprintf(stderr, "[%d] %s %s: ", (int)status, name, category);
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

#define LOOKUP(type, name) \
    type name = (type)dlsym(lib, #name); \
    if (name == NULL) { fprintf(stderr, "no %s in %s\n", #name, argv[1]); return 2; }

#define CHECK(call) \
    do { fmi2Status s_ = (call); \
         if (s_ != fmi2OK) { fprintf(stderr, "%s returned %d\n", #call, (int)s_); return 3; } \
    } while (0)

int main(int argc, char **argv)
{
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    void *lib;
    fmi2Component c;
    double T;
    long k = 0;
    int i, first_out = argc;
    char line[4096], resources[4096];
    char *cut;
    int up;
    if (argc < 4) {
        fprintf(stderr, "usage: fmu_host BINARY GUID T [r|i|b:VR=VALUE ...] -- OUT ...\n");
        return 2;
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (lib == NULL) {
        fprintf(stderr, "cannot load %s: %s\n", argv[1], dlerror());
        return 2;
    }
    {
        LOOKUP(fmi2InstantiateTYPE *, fmi2Instantiate)
        LOOKUP(fmi2SetupExperimentTYPE *, fmi2SetupExperiment)
        LOOKUP(fmi2EnterInitializationModeTYPE *, fmi2EnterInitializationMode)
        LOOKUP(fmi2ExitInitializationModeTYPE *, fmi2ExitInitializationMode)
        LOOKUP(fmi2SetRealTYPE *, fmi2SetReal)
        LOOKUP(fmi2SetIntegerTYPE *, fmi2SetInteger)
        LOOKUP(fmi2SetBooleanTYPE *, fmi2SetBoolean)
        LOOKUP(fmi2GetRealTYPE *, fmi2GetReal)
        LOOKUP(fmi2GetIntegerTYPE *, fmi2GetInteger)
        LOOKUP(fmi2DoStepTYPE *, fmi2DoStep)
        LOOKUP(fmi2TerminateTYPE *, fmi2Terminate)
        LOOKUP(fmi2FreeInstanceTYPE *, fmi2FreeInstance)
        T = strtod(argv[3], NULL);
        /* BINARY is <fmu>/binaries/<platform>/<file>: the resources are <fmu>/resources */
        snprintf(resources, sizeof resources, "file://%s", argv[1]);
        for (up = 0; up < 3; up++) {
            cut = strrchr(resources, '/');
            if (cut != NULL) *cut = '\0';
        }
        strncat(resources, "/resources", sizeof resources - strlen(resources) - 1);
        c = fmi2Instantiate("controller", fmi2CoSimulation, argv[2], resources, &callbacks,
                            fmi2False, fmi2True);
        if (c == NULL) {
            fprintf(stderr, "fmi2Instantiate gave no instance\n");
            return 3;
        }
        CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        CHECK(fmi2EnterInitializationMode(c));
        for (i = 4; i < argc; i++) {
            fmi2ValueReference vr;
            char *eq;
            if (strcmp(argv[i], "--") == 0) {
                first_out = i + 1;
                break;
            }
            eq = strchr(argv[i], '=');
            if (argv[i][1] != ':' || eq == NULL) {
                fprintf(stderr, "not a parameter: %s\n", argv[i]);
                return 2;
            }
            vr = (fmi2ValueReference)strtoul(argv[i] + 2, NULL, 10);
            if (argv[i][0] == 'r') {
                fmi2Real v = strtod(eq + 1, NULL);
                CHECK(fmi2SetReal(c, &vr, 1, &v));
            } else if (argv[i][0] == 'i') {
                fmi2Integer v = (fmi2Integer)strtol(eq + 1, NULL, 10);
                CHECK(fmi2SetInteger(c, &vr, 1, &v));
            } else {
                fmi2Boolean v = strcmp(eq + 1, "true") == 0 ? fmi2True : fmi2False;
                CHECK(fmi2SetBoolean(c, &vr, 1, &v));
            }
        }
        CHECK(fmi2ExitInitializationMode(c));
        while (fgets(line, sizeof line, stdin) != NULL) {
            char *p = line, *end;
            for (;;) {
                fmi2ValueReference vr = (fmi2ValueReference)strtoul(p, &end, 10);
                fmi2Real v;
                if (end == p) break;
                v = strtod(end, &p);
                CHECK(fmi2SetReal(c, &vr, 1, &v));
            }
            CHECK(fmi2DoStep(c, (double)k * T, T, fmi2True));
            k += 1;
            for (i = first_out; i < argc; i++) {
                fmi2ValueReference vr = (fmi2ValueReference)strtoul(argv[i], &end, 10);
                if (*end == 'i') {
                    fmi2Integer v;
                    CHECK(fmi2GetInteger(c, &vr, 1, &v));
                    printf("%s%d", i > first_out ? " " : "", (int)v);
                } else {
                    fmi2Real v;
                    CHECK(fmi2GetReal(c, &vr, 1, &v));
                    printf("%s%a", i > first_out ? " " : "", v);
                }
            }
            putchar('\n');
        }
        CHECK(fmi2Terminate(c));
        fmi2FreeInstance(c);
    }
    dlclose(lib);
    return 0;
}
