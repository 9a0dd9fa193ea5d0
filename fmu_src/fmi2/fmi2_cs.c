/* fmi2_cs.c: the FMI 2.0 Co-Simulation interface of papwc's native FMUs, written once.
 *
 * A model gives its data block and functions (fmu_model.h); this file gives every fmi2
 * function of the standard and the rules a host meets:
 *
 * - fmi2Instantiate returns NULL for another GUID, a Model Exchange request or a missing
 *   instance name (logged when a logger is given);
 * - parameters are set only before fmi2ExitInitializationMode; there every parameter is
 *   checked (its range, the rules between parameters), each problem logged with its value
 *   and what is allowed, and initialization is refused with fmi2Error (the instance stays
 *   in initialization mode: the host may correct the parameters and try again);
 * - every refused call returns fmi2Error and changes nothing; fmi2DoStep returns
 *   fmi2Discard (the state left as it was) for a step size that is not > 0 and finite and
 *   for a step the model refuses (a non-finite input), fmi2Error for a communication point
 *   that is not the end of the last step and for a step that ends past the stop time that
 *   fmi2SetupExperiment defined (FMI 2.0: computing past stopTime is an error);
 * - a refusal is logged (category logStatusError or logStatusDiscard) when logging is on;
 *   a refused initialization and the first refused step of an instance are also written
 *   to stderr as one line, unless the environment sets PAPWC_FMU_STDERR=0 (so that a run
 *   with logging off, fmpy's default, still says why it stopped);
 * - an FMU state is a copy of the whole instance (phase, time, model data); a serialized
 *   one carries the GUID and its size, and one that does not fit is refused; an instance
 *   whose initialization was refused gives no state (fmi2GetFMUstate returns fmi2Error:
 *   such a state could never step);
 * - the Model Exchange functions exist (a host may look them all up) and return fmi2Error.
 *
 * Memory: one block per instance and one per FMU state, freed by fmi2FreeInstance and
 * fmi2FreeFMUstate.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_model.h"

/* ---------------------------------------------------------------------------------------- */
/* Phases of an instance (FMI 2.0 CS state machine). */
typedef enum {
    PHASE_INSTANTIATED = 1,
    PHASE_INITIALIZATION = 2,
    PHASE_STEP_COMPLETE = 3,
    PHASE_TERMINATED = 4
} Phase;

#define CATEGORY_ERROR 1u
#define CATEGORY_DISCARD 2u
#define CATEGORY_ALL (CATEGORY_ERROR | CATEGORY_DISCARD)

#define MESSAGE_LEN 1024

typedef struct {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment environment;
    char *name;
    unsigned categories; /* categories logged; 0: logging off */
    int step_told;       /* a refused step has been written to stderr */
    int discarded;       /* the last step was refused with fmi2Discard */
    int stop_defined;    /* fmi2SetupExperiment defined a stop time */
    int init_refused;    /* fmi2ExitInitializationMode refused the parameters (told) */
    Phase phase;
    double time;         /* the last communication point, s */
    double stop_time;    /* the stop time, s (if stop_defined) */
    char refused[MESSAGE_LEN]; /* why initialization was refused (if init_refused) */
    void *model;
} Instance;

/* An FMU state: the phase, the time and a copy of the model data. */
#define STATE_MAGIC 0x50415057u /* "PAPW" */
typedef struct {
    uint32_t magic;
    uint32_t phase;
    double time;
} StateHead;

/* A serialized state: this marker, the GUID (zero-padded), then StateHead and the data. */
static const char SERIAL_MAGIC[8] = {'P', 'A', 'P', 'W', 'C', 'S', 'T', '1'};
#define SERIAL_GUID_LEN 64

/* ---------------------------------------------------------------------------------------- */
/* Numbers and messages. */

void fmu_format_real(double value, char *out, size_t len) {
    char buf[64];
    int digits, exponent, decimals;
    const char *e;
    if (len == 0) return;
    if (isnan(value)) {
        snprintf(out, len, "nan");
        return;
    }
    if (isinf(value)) {
        snprintf(out, len, value > 0 ? "inf" : "-inf");
        return;
    }
    if (value == 0.0) {
        snprintf(out, len, signbit(value) ? "-0.0" : "0.0");
        return;
    }
    for (digits = 1; digits < 17; digits++) {
        snprintf(buf, sizeof buf, "%.*e", digits - 1, value);
        if (strtod(buf, NULL) == value) break;
    }
    snprintf(buf, sizeof buf, "%.*e", digits - 1, value);
    e = strchr(buf, 'e');
    exponent = e != NULL ? atoi(e + 1) : 0;
    if (exponent >= -4 && exponent < 16) { /* as repr: fixed for 1e-4 <= |x| < 1e16 */
        decimals = digits - 1 - exponent;
        if (decimals < 0) decimals = 0;
        snprintf(out, len, "%.*f%s", decimals, value, decimals == 0 ? ".0" : "");
    } else {
        snprintf(out, len, "%s", buf);
    }
}

static int stderr_wanted(void) {
    const char *flag = getenv("PAPWC_FMU_STDERR");
    return !(flag != NULL && strcmp(flag, "0") == 0);
}

/* One line on stderr naming the model and the instance. */
static void tell(const Instance *inst, const char *message) {
    if (!stderr_wanted()) return;
    fprintf(stderr, "%s %s: %s\n", MODEL_IDENTIFIER_STRING, inst->name, message);
    fflush(stderr);
}

/* Log a message (a host formats it as printf does: every '%' is written '%%'). */
static void log_text(const Instance *inst, fmi2Status status, unsigned category,
                     const char *text) {
    char escaped[2 * MESSAGE_LEN + 1];
    char line[MESSAGE_LEN];
    size_t i, j = 0;
    const char *name;
    if (inst == NULL || inst->logger == NULL || (inst->categories & category) == 0) return;
    snprintf(line, sizeof line, "%s: %s", inst->name, text);
    for (i = 0; line[i] != '\0' && j + 2 < sizeof escaped; i++) {
        if (line[i] == '%') escaped[j++] = '%';
        escaped[j++] = line[i];
    }
    escaped[j] = '\0';
    name = category == CATEGORY_DISCARD ? "logStatusDiscard" : "logStatusError";
    inst->logger(inst->environment, inst->name, status, name, escaped);
}

static fmi2Status refuse(const Instance *inst, fmi2Status status, const char *format, ...) {
    char text[MESSAGE_LEN];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(inst, status, status == fmi2Discard ? CATEGORY_DISCARD : CATEGORY_ERROR, text);
    return status;
}

static const char *phase_name(Phase phase) {
    switch (phase) {
        case PHASE_INSTANTIATED: return "instantiated (before fmi2EnterInitializationMode)";
        case PHASE_INITIALIZATION: return "in initialization mode";
        case PHASE_STEP_COMPLETE: return "stepping (initialization has ended)";
        case PHASE_TERMINATED: return "terminated (fmi2Terminate)";
    }
    return "in an unknown phase";
}

/* fmi2Error unless the instance is in one of the phases of mask (bit 1 << phase). */
static fmi2Status check_phase(const Instance *inst, const char *function, unsigned mask) {
    if (mask & (1u << inst->phase)) return fmi2OK;
    return refuse(inst, fmi2Error, "%s refused: the instance is %s", function,
                  phase_name(inst->phase));
}

#define IN(p) (1u << (p))

static Instance *instance_of(fmi2Component c) { return (Instance *)c; }

#define INSTANCE_OR_ERROR(c) \
    Instance *inst = instance_of(c); \
    if (inst == NULL) return fmi2Error

/* ---------------------------------------------------------------------------------------- */
/* Creation and destruction. */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

static void no_instance(const fmi2CallbackFunctions *functions, fmi2String name,
                        const char *text) {
    if (functions != NULL && functions->logger != NULL) {
        functions->logger(functions->componentEnvironment, name != NULL ? name : "", fmi2Error,
                          "logStatusError", text);
    }
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Instance *inst;
    char text[MESSAGE_LEN];
    size_t n;
    (void)fmuResourceLocation;
    (void)visible;
    if (instanceName == NULL || instanceName[0] == '\0') {
        no_instance(functions, instanceName,
                    "fmi2Instantiate refused: the instance name is missing or empty");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        snprintf(text, sizeof text, "%s: fmi2Instantiate refused: " MODEL_IDENTIFIER_STRING
                 " is a Co-Simulation FMU (fmuType fmi2CoSimulation), not Model Exchange",
                 instanceName);
        no_instance(functions, instanceName, text);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        snprintf(text, sizeof text, "%s: fmi2Instantiate refused: GUID %.80s is not this "
                 "FMU's, " MODEL_GUID, instanceName, fmuGUID != NULL ? fmuGUID : "(NULL)");
        no_instance(functions, instanceName, text);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) return NULL;
    n = strlen(instanceName);
    inst->name = (char *)malloc(n + 1);
    inst->model = calloc(1, model_data_size());
    if (inst->name == NULL || inst->model == NULL) {
        free(inst->name);
        free(inst->model);
        free(inst);
        return NULL;
    }
    memcpy(inst->name, instanceName, n + 1);
    inst->logger = functions != NULL ? functions->logger : NULL;
    inst->environment = functions != NULL ? functions->componentEnvironment : NULL;
    inst->categories = loggingOn ? CATEGORY_ALL : 0u;
    inst->phase = PHASE_INSTANTIATED;
    inst->time = 0.0;
    model_defaults(inst->model);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = instance_of(c);
    if (inst == NULL) return;
    free(inst->model);
    free(inst->name);
    free(inst);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    unsigned chosen = 0;
    size_t i;
    INSTANCE_OR_ERROR(c);
    if (nCategories == 0) {
        inst->categories = loggingOn ? CATEGORY_ALL : 0u;
        return fmi2OK;
    }
    if (categories == NULL) return refuse(inst, fmi2Error, "fmi2SetDebugLogging refused: "
                                          "%u categories named, none given",
                                          (unsigned)nCategories);
    for (i = 0; i < nCategories; i++) {
        const char *name = categories[i] != NULL ? categories[i] : "(NULL)";
        if (strcmp(name, "logStatusError") == 0) chosen |= CATEGORY_ERROR;
        else if (strcmp(name, "logStatusDiscard") == 0) chosen |= CATEGORY_DISCARD;
        else if (strcmp(name, "logAll") == 0) chosen |= CATEGORY_ALL;
        else return refuse(inst, fmi2Error, "fmi2SetDebugLogging refused: unknown log "
                           "category %.80s; categories: logStatusError, logStatusDiscard, "
                           "logAll", name);
    }
    inst->categories = loggingOn ? (inst->categories | chosen) : (inst->categories & ~chosen);
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Initialization, termination, reset. */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    char text[48], stop[48];
    INSTANCE_OR_ERROR(c);
    (void)toleranceDefined;
    (void)tolerance;
    if (check_phase(inst, "fmi2SetupExperiment", IN(PHASE_INSTANTIATED)) != fmi2OK) {
        return fmi2Error;
    }
    fmu_format_real(startTime, text, sizeof text);
    if (!isfinite(startTime)) {
        return refuse(inst, fmi2Error, "fmi2SetupExperiment refused: start time %s s is not "
                      "a finite number", text);
    }
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime)) {
        fmu_format_real(stopTime, stop, sizeof stop);
        return refuse(inst, fmi2Error, "fmi2SetupExperiment refused: stop time %s s must be a "
                      "finite number >= the start time %s s", stop, text);
    }
    inst->time = startTime;
    inst->stop_defined = stopTimeDefined ? 1 : 0;
    inst->stop_time = stopTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    INSTANCE_OR_ERROR(c);
    if (check_phase(inst, "fmi2EnterInitializationMode", IN(PHASE_INSTANTIATED)) != fmi2OK) {
        return fmi2Error;
    }
    inst->phase = PHASE_INITIALIZATION;
    return fmi2OK;
}

typedef struct {
    Instance *inst;
    char joined[MESSAGE_LEN];
} Problems;

static void report_problem(void *context, const char *message) {
    Problems *found = (Problems *)context;
    size_t used = strlen(found->joined);
    log_text(found->inst, fmi2Error, CATEGORY_ERROR, message);
    if (used + 3 < sizeof found->joined) {
        snprintf(found->joined + used, sizeof found->joined - used, "%s%s",
                 used > 0 ? "; " : "", message);
    }
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Problems found;
    char line[MESSAGE_LEN + 80];
    INSTANCE_OR_ERROR(c);
    if (check_phase(inst, "fmi2ExitInitializationMode", IN(PHASE_INITIALIZATION)) != fmi2OK) {
        return fmi2Error;
    }
    found.inst = inst;
    found.joined[0] = '\0';
    if (model_check(inst->model, report_problem, &found) > 0) {
        snprintf(line, sizeof line, "%s; initialization refused (fmi2Error)", found.joined);
        tell(inst, line);
        inst->init_refused = 1;
        memcpy(inst->refused, found.joined, sizeof inst->refused);
        return fmi2Error; /* still in initialization mode: the parameters may be corrected */
    }
    model_start(inst->model);
    inst->init_refused = 0;
    inst->phase = PHASE_STEP_COMPLETE;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    INSTANCE_OR_ERROR(c);
    if (check_phase(inst, "fmi2Terminate", IN(PHASE_INITIALIZATION) | IN(PHASE_STEP_COMPLETE))
        != fmi2OK) {
        return fmi2Error;
    }
    inst->phase = PHASE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    INSTANCE_OR_ERROR(c);
    memset(inst->model, 0, model_data_size());
    model_defaults(inst->model);
    inst->phase = PHASE_INSTANTIATED;
    inst->time = 0.0;
    inst->step_told = 0;
    inst->discarded = 0;
    inst->stop_defined = 0;
    inst->init_refused = 0;
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Getting and setting values. */

static const char *type_name(ModelType type) {
    switch (type) {
        case MODEL_REAL: return "Real";
        case MODEL_INTEGER: return "Integer";
        case MODEL_BOOLEAN: return "Boolean";
        case MODEL_STRING: return "String";
    }
    return "?";
}

/* fmi2OK if vr is a variable of type want, else fmi2Error (logged). */
static fmi2Status lookup(const Instance *inst, const char *function, fmi2ValueReference vr,
                         ModelType want, ModelCausality *causality, const char **name) {
    ModelType type = MODEL_REAL;
    *causality = model_variable(vr, &type, name);
    if (*causality == MODEL_NO_VARIABLE) {
        return refuse(inst, fmi2Error, "%s refused: no variable has value reference %u",
                      function, (unsigned)vr);
    }
    if (type != want) {
        return refuse(inst, fmi2Error, "%s refused: value reference %u is the %s variable %s, "
                      "not a %s", function, (unsigned)vr, type_name(type), *name,
                      type_name(want));
    }
    return fmi2OK;
}

static fmi2Status check_get(const Instance *inst, const char *function,
                            const fmi2ValueReference vr[], size_t nvr, const void *value,
                            ModelType type) {
    ModelCausality causality;
    const char *name;
    size_t i;
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return refuse(inst, fmi2Error, "%s refused: NULL value references or values",
                      function);
    }
    for (i = 0; i < nvr; i++) {
        if (lookup(inst, function, vr[i], type, &causality, &name) != fmi2OK) return fmi2Error;
    }
    return fmi2OK;
}

/* The model's Boolean as an fmi2Boolean. */
static fmi2Boolean get_boolean(const void *model, fmi2ValueReference vr) {
    return model_get_boolean(model, vr) ? fmi2True : fmi2False;
}

/* fmi2Get<Type>: every value reference checked (nothing read if one is refused), then each
 * value read from the model by read(model, vr). */
#define GET_VALUES(function, type, model_type, read) \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                        type value[]) { \
        size_t i; \
        INSTANCE_OR_ERROR(c); \
        if (check_get(inst, #function, vr, nvr, value, model_type) != fmi2OK) { \
            return fmi2Error; \
        } \
        for (i = 0; i < nvr; i++) value[i] = read(inst->model, vr[i]); \
        return fmi2OK; \
    }

GET_VALUES(fmi2GetReal, fmi2Real, MODEL_REAL, model_get_real)
GET_VALUES(fmi2GetInteger, fmi2Integer, MODEL_INTEGER, model_get_integer)
GET_VALUES(fmi2GetBoolean, fmi2Boolean, MODEL_BOOLEAN, get_boolean)

GET_VALUES(fmi2GetString, fmi2String, MODEL_STRING, model_get_string)

/* Text of a value of a set call, for messages. */
static void value_text(ModelType type, const void *values, size_t i, char *out, size_t len) {
    const char *text;
    if (type == MODEL_STRING) {
        text = ((const fmi2String *)values)[i];
        snprintf(out, len, "'%.32s'", text != NULL ? text : "(NULL)");
    } else if (type == MODEL_REAL) fmu_format_real(((const fmi2Real *)values)[i], out, len);
    else if (type == MODEL_INTEGER) snprintf(out, len, "%d", (int)((const fmi2Integer *)values)[i]);
    else snprintf(out, len, "%s", ((const fmi2Boolean *)values)[i] ? "true" : "false");
}

static void current_text(const Instance *inst, ModelType type, fmi2ValueReference vr,
                         char *out, size_t len) {
    if (type == MODEL_STRING) snprintf(out, len, "'%.32s'", model_get_string(inst->model, vr));
    else if (type == MODEL_REAL) fmu_format_real(model_get_real(inst->model, vr), out, len);
    else if (type == MODEL_INTEGER) snprintf(out, len, "%d", model_get_integer(inst->model, vr));
    else snprintf(out, len, "%s", model_get_boolean(inst->model, vr) ? "true" : "false");
}

/* Whether every value of a set call may be set now: fmi2OK, or fmi2Error (logged, nothing
 * set). */
static fmi2Status check_set(const Instance *inst, const char *function,
                            const fmi2ValueReference vr[], size_t nvr, const void *values,
                            ModelType type) {
    ModelCausality causality;
    const char *name;
    char given[48], kept[48];
    size_t i;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return refuse(inst, fmi2Error, "%s refused: NULL value references or values",
                      function);
    }
    for (i = 0; i < nvr; i++) {
        if (lookup(inst, function, vr[i], type, &causality, &name) != fmi2OK) return fmi2Error;
        if (causality == MODEL_INPUT && inst->phase != PHASE_TERMINATED) continue;
        value_text(type, values, i, given, sizeof given); /* only for a message */
        if (causality == MODEL_OUTPUT) {
            return refuse(inst, fmi2Error, "%s is an output and cannot be set: %s refused",
                          name, given);
        }
        if (causality == MODEL_PARAMETER && inst->phase != PHASE_INSTANTIATED &&
            inst->phase != PHASE_INITIALIZATION) {
            current_text(inst, type, vr[i], kept, sizeof kept);
            return refuse(inst, fmi2Error, "parameter %s cannot be set after initialization: "
                          "%s refused, it stays %s", name, given, kept);
        }
        if (causality == MODEL_INPUT && inst->phase == PHASE_TERMINATED) {
            return refuse(inst, fmi2Error, "input %s cannot be set after fmi2Terminate: %s "
                          "refused", name, given);
        }
    }
    return fmi2OK;
}

/* The fmi2Boolean given as the model's Boolean. */
static void set_boolean(void *model, fmi2ValueReference vr, fmi2Boolean value) {
    model_set_boolean(model, vr, value != fmi2False);
}

/* fmi2Set<Type>: every value checked (nothing set if one is refused), then each set in the
 * model by write(model, vr, value). */
#define SET_VALUES(function, type, model_type, write) \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                        const type value[]) { \
        size_t i; \
        INSTANCE_OR_ERROR(c); \
        if (check_set(inst, #function, vr, nvr, value, model_type) != fmi2OK) { \
            return fmi2Error; \
        } \
        for (i = 0; i < nvr; i++) write(inst->model, vr[i], value[i]); \
        return fmi2OK; \
    }

SET_VALUES(fmi2SetReal, fmi2Real, MODEL_REAL, model_set_real)
SET_VALUES(fmi2SetInteger, fmi2Integer, MODEL_INTEGER, model_set_integer)
SET_VALUES(fmi2SetBoolean, fmi2Boolean, MODEL_BOOLEAN, set_boolean)

/* A String given to fmi2SetString, NULL read as "". */
static void set_string(void *model, fmi2ValueReference vr, fmi2String value) {
    model_set_string(model, vr, value != NULL ? value : "");
}

SET_VALUES(fmi2SetString, fmi2String, MODEL_STRING, set_string)

/* ---------------------------------------------------------------------------------------- */
/* FMU states. */

static size_t state_size(void) { return sizeof(StateHead) + model_data_size(); }

static StateHead *new_state(void) { return (StateHead *)calloc(1, state_size()); }

static void copy_into_state(const Instance *inst, StateHead *state) {
    state->magic = STATE_MAGIC;
    state->phase = (uint32_t)inst->phase;
    state->time = inst->time;
    memcpy(state + 1, inst->model, model_data_size());
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    StateHead *state;
    INSTANCE_OR_ERROR(c);
    if (FMUstate == NULL) return refuse(inst, fmi2Error, "fmi2GetFMUstate refused: NULL "
                                        "pointer to the state");
    if (inst->init_refused) {
        char line[MESSAGE_LEN + 200];
        snprintf(line, sizeof line, "fmi2GetFMUstate refused: fmi2ExitInitializationMode "
                 "refused this instance's parameters (%s), so a state of it could never step; "
                 "correct the parameters and initialize first", inst->refused);
        tell(inst, line);
        return refuse(inst, fmi2Error, "%s", line);
    }
    state = (StateHead *)*FMUstate;
    if (state != NULL && state->magic != STATE_MAGIC) {
        return refuse(inst, fmi2Error, "fmi2GetFMUstate refused: the state to overwrite is "
                      "not one of " MODEL_IDENTIFIER_STRING);
    }
    if (state == NULL) {
        state = new_state();
        if (state == NULL) return refuse(inst, fmi2Error, "fmi2GetFMUstate: out of memory");
    }
    copy_into_state(inst, state);
    *FMUstate = state;
    return fmi2OK;
}

/* Whether state may become the instance's: fmi2OK, or fmi2Error with why not. */
static fmi2Status check_state(const Instance *inst, const char *function,
                              const StateHead *state) {
    char why[MESSAGE_LEN];
    char text[48];
    if (state == NULL || state->magic != STATE_MAGIC) {
        return refuse(inst, fmi2Error, "%s refused: not a state of " MODEL_IDENTIFIER_STRING
                      "; the instance keeps its state", function);
    }
    if (state->phase < PHASE_INSTANTIATED || state->phase > PHASE_TERMINATED) {
        return refuse(inst, fmi2Error, "%s refused: the state's phase %u is not one of an "
                      "instance; the instance keeps its state", function,
                      (unsigned)state->phase);
    }
    if (!isfinite(state->time)) {
        fmu_format_real(state->time, text, sizeof text);
        return refuse(inst, fmi2Error, "%s refused: the state's time %s s is not finite; the "
                      "instance keeps its state", function, text);
    }
    if (model_state_check(state + 1, state->phase >= PHASE_STEP_COMPLETE, why, sizeof why)) {
        return refuse(inst, fmi2Error, "%s refused: %s; the instance keeps its state",
                      function, why);
    }
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const StateHead *state = (const StateHead *)FMUstate;
    INSTANCE_OR_ERROR(c);
    if (check_state(inst, "fmi2SetFMUstate", state) != fmi2OK) return fmi2Error;
    inst->phase = (Phase)state->phase;
    inst->time = state->time;
    inst->discarded = 0;
    inst->init_refused = 0; /* the state's own phase says what the instance may do now */
    memcpy(inst->model, state + 1, model_data_size());
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    StateHead *state;
    INSTANCE_OR_ERROR(c);
    if (FMUstate == NULL || *FMUstate == NULL) return fmi2OK;
    state = (StateHead *)*FMUstate;
    if (state->magic != STATE_MAGIC) {
        return refuse(inst, fmi2Error, "fmi2FreeFMUstate refused: not a state of "
                      MODEL_IDENTIFIER_STRING);
    }
    state->magic = 0;
    free(state);
    *FMUstate = NULL;
    return fmi2OK;
}

static size_t serialized_size(void) {
    return sizeof SERIAL_MAGIC + SERIAL_GUID_LEN + state_size();
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    const StateHead *state = (const StateHead *)FMUstate;
    INSTANCE_OR_ERROR(c);
    if (size == NULL) return refuse(inst, fmi2Error, "fmi2SerializedFMUstateSize refused: "
                                    "NULL size");
    if (state == NULL || state->magic != STATE_MAGIC) {
        return refuse(inst, fmi2Error, "fmi2SerializedFMUstateSize refused: not a state of "
                      MODEL_IDENTIFIER_STRING);
    }
    *size = serialized_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    const StateHead *state = (const StateHead *)FMUstate;
    char guid[SERIAL_GUID_LEN];
    INSTANCE_OR_ERROR(c);
    if (state == NULL || state->magic != STATE_MAGIC) {
        return refuse(inst, fmi2Error, "fmi2SerializeFMUstate refused: not a state of "
                      MODEL_IDENTIFIER_STRING);
    }
    if (serializedState == NULL || size != serialized_size()) {
        return refuse(inst, fmi2Error, "fmi2SerializeFMUstate refused: the buffer holds %u "
                      "bytes, a state takes %u (fmi2SerializedFMUstateSize)", (unsigned)size,
                      (unsigned)serialized_size());
    }
    memset(guid, 0, sizeof guid);
    strncpy(guid, MODEL_GUID, sizeof guid - 1);
    memcpy(serializedState, SERIAL_MAGIC, sizeof SERIAL_MAGIC);
    memcpy(serializedState + sizeof SERIAL_MAGIC, guid, sizeof guid);
    memcpy(serializedState + sizeof SERIAL_MAGIC + sizeof guid, state, state_size());
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    char guid[SERIAL_GUID_LEN];
    StateHead *state;
    INSTANCE_OR_ERROR(c);
    if (FMUstate == NULL) return refuse(inst, fmi2Error, "fmi2DeSerializeFMUstate refused: "
                                        "NULL pointer to the state");
    if (serializedState == NULL || size != serialized_size()) {
        return refuse(inst, fmi2Error, "fmi2DeSerializeFMUstate refused: %u bytes are not a "
                      "serialized state of " MODEL_IDENTIFIER_STRING " (%u bytes)",
                      (unsigned)size, (unsigned)serialized_size());
    }
    if (memcmp(serializedState, SERIAL_MAGIC, sizeof SERIAL_MAGIC) != 0) {
        return refuse(inst, fmi2Error, "fmi2DeSerializeFMUstate refused: the bytes are not a "
                      "serialized state of a papwc FMU");
    }
    memset(guid, 0, sizeof guid);
    strncpy(guid, MODEL_GUID, sizeof guid - 1);
    if (memcmp(serializedState + sizeof SERIAL_MAGIC, guid, sizeof guid) != 0) {
        return refuse(inst, fmi2Error, "fmi2DeSerializeFMUstate refused: the state was saved "
                      "by another FMU (its GUID is not " MODEL_GUID ")");
    }
    state = new_state();
    if (state == NULL) return refuse(inst, fmi2Error, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(state, serializedState + sizeof SERIAL_MAGIC + sizeof guid, state_size());
    if (check_state(inst, "fmi2DeSerializeFMUstate", state) != fmi2OK) {
        free(state);
        return fmi2Error;
    }
    *FMUstate = state; /* a new state: what *FMUstate held on entry is not read */
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    INSTANCE_OR_ERROR(c);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown;
    (void)dvUnknown;
    return refuse(inst, fmi2Error, "fmi2GetDirectionalDerivative refused: "
                  MODEL_IDENTIFIER_STRING " does not provide directional derivatives");
}

/* ---------------------------------------------------------------------------------------- */
/* Co-Simulation. */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    INSTANCE_OR_ERROR(c);
    (void)vr; (void)order; (void)value;
    if (nvr == 0) return fmi2OK;
    return refuse(inst, fmi2Error, "fmi2SetRealInputDerivatives refused: the inputs are held "
                  "constant over a step (canInterpolateInputs is false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    INSTANCE_OR_ERROR(c);
    (void)vr; (void)order; (void)value;
    if (nvr == 0) return fmi2OK;
    return refuse(inst, fmi2Error, "fmi2GetRealOutputDerivatives refused: "
                  MODEL_IDENTIFIER_STRING " gives no output derivatives "
                  "(maxOutputDerivativeOrder is 0)");
}

/* A refused step: the message, logged (status) and, the first time, told on stderr. */
static fmi2Status refuse_step(Instance *inst, fmi2Status status, double t, double h,
                              const char *why, int tell_it) {
    char t_text[48], h_text[48], line[MESSAGE_LEN + 160];
    fmu_format_real(t, t_text, sizeof t_text);
    fmu_format_real(h, h_text, sizeof h_text);
    snprintf(line, sizeof line, "doStep(t = %s s, h = %s s) refused: %s; the state is left as "
             "it was", t_text, h_text, why);
    log_text(inst, status, status == fmi2Discard ? CATEGORY_DISCARD : CATEGORY_ERROR, line);
    if (tell_it && !inst->step_told) {
        inst->step_told = 1;
        snprintf(line, sizeof line, "doStep(t = %s s, h = %s s) refused: %s; the state is left "
                 "as it was (later refusals are only logged)", t_text, h_text, why);
        tell(inst, line);
    }
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    char why[MESSAGE_LEN], last[48];
    double t = currentCommunicationPoint, h = communicationStepSize, tol;
    INSTANCE_OR_ERROR(c);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst->phase != PHASE_STEP_COMPLETE) {
        snprintf(why, sizeof why, "the instance is %s%s", phase_name(inst->phase),
                 inst->phase == PHASE_INITIALIZATION
                     ? " (fmi2ExitInitializationMode refused the parameters or was not called)"
                     : "");
        /* this instance's refused initialization has been told already */
        return refuse_step(inst, fmi2Error, t, h, why, !inst->init_refused);
    }
    if (!(h > 0.0) || !isfinite(h)) {
        fmu_format_real(h, last, sizeof last);
        snprintf(why, sizeof why, "step size %s s must be finite and > 0", last);
        inst->discarded = 1;
        return refuse_step(inst, fmi2Discard, t, h, why, 1);
    }
    tol = 1e-9 * (fabs(inst->time) > h ? fabs(inst->time) : h);
    if (!isfinite(t) || fabs(t - inst->time) > tol) {
        fmu_format_real(inst->time, last, sizeof last);
        snprintf(why, sizeof why, "the communication point must be the end of the last step, "
                 "t = %s s", last);
        return refuse_step(inst, fmi2Error, t, h, why, 1);
    }
    if (inst->stop_defined &&
        t + h > inst->stop_time + 1e-9 * (fabs(inst->stop_time) > h ? fabs(inst->stop_time) : h)) {
        char end[48], stop[48];
        fmu_format_real(t + h, end, sizeof end);
        fmu_format_real(inst->stop_time, stop, sizeof stop);
        snprintf(why, sizeof why, "the step ends at t = %s s, past the stop time %s s that "
                 "fmi2SetupExperiment defined (FMI 2.0: computing past stopTime is an error)",
                 end, stop);
        return refuse_step(inst, fmi2Error, t, h, why, 1);
    }
    if (model_step(inst->model, h, why, sizeof why) != 0) {
        inst->discarded = 1;
        return refuse_step(inst, fmi2Discard, t, h, why, 1);
    }
    inst->time = t + h;
    inst->discarded = 0;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    INSTANCE_OR_ERROR(c);
    return refuse(inst, fmi2Error, "fmi2CancelStep refused: doStep never runs asynchronously");
}

/* A status function that gives nothing: refused with fmi2Discard and the reason. */
#define NO_STATUS(function, type, reason) \
    fmi2Status function(fmi2Component c, const fmi2StatusKind s, type *value) { \
        INSTANCE_OR_ERROR(c); \
        (void)s; (void)value; \
        return refuse(inst, fmi2Discard, #function ": " reason); \
    }

NO_STATUS(fmi2GetStatus, fmi2Status, "no status to give (doStep never runs asynchronously)")
NO_STATUS(fmi2GetIntegerStatus, fmi2Integer, "no integer status to give")
NO_STATUS(fmi2GetStringStatus, fmi2String, "no string status to give")

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    INSTANCE_OR_ERROR(c);
    if (s == fmi2LastSuccessfulTime && value != NULL) {
        *value = inst->time;
        return fmi2OK;
    }
    return refuse(inst, fmi2Discard, "fmi2GetRealStatus: only fmi2LastSuccessfulTime is given");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    INSTANCE_OR_ERROR(c);
    if (s == fmi2Terminated && value != NULL) {
        /* after a refused step the simulation cannot go on as the host asked: it should end
         * (or restore a state) rather than repeat the same step */
        *value = inst->discarded ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return refuse(inst, fmi2Discard, "fmi2GetBooleanStatus: only fmi2Terminated is given");
}

/* ---------------------------------------------------------------------------------------- */
/* Model Exchange: not provided (a Co-Simulation FMU); each returns fmi2Error. */

#define NOT_MODEL_EXCHANGE(function) \
    return refuse(instance_of(c), fmi2Error, function " refused: " MODEL_IDENTIFIER_STRING \
                  " is a Co-Simulation FMU (no Model Exchange)")

fmi2Status fmi2EnterEventMode(fmi2Component c) { NOT_MODEL_EXCHANGE("fmi2EnterEventMode"); }

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    (void)eventInfo;
    NOT_MODEL_EXCHANGE("fmi2NewDiscreteStates");
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    NOT_MODEL_EXCHANGE("fmi2EnterContinuousTimeMode");
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    NOT_MODEL_EXCHANGE("fmi2CompletedIntegratorStep");
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    (void)time;
    NOT_MODEL_EXCHANGE("fmi2SetTime");
}

/* A Model Exchange function that takes an array of n values. */
#define NOT_MODEL_EXCHANGE_ARRAY(function, type) \
    fmi2Status function(fmi2Component c, type values[], size_t n) { \
        (void)values; (void)n; \
        NOT_MODEL_EXCHANGE(#function); \
    }

NOT_MODEL_EXCHANGE_ARRAY(fmi2SetContinuousStates, const fmi2Real)
NOT_MODEL_EXCHANGE_ARRAY(fmi2GetDerivatives, fmi2Real)
NOT_MODEL_EXCHANGE_ARRAY(fmi2GetEventIndicators, fmi2Real)
NOT_MODEL_EXCHANGE_ARRAY(fmi2GetContinuousStates, fmi2Real)
NOT_MODEL_EXCHANGE_ARRAY(fmi2GetNominalsOfContinuousStates, fmi2Real)
