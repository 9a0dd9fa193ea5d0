/* fmu_model.c: FrictionPlant bound to the FMI glue (fmu_src/fmi2/fmi2_cs.c).
 *
 * The model data is the plant's parameters (FpParams), its state (FpState), the input
 * and whether the simulation has started: plain data, so an FMU state is a copy of it.
 * Value references, types and ranges come from plant_vars.h (generated from
 * papwc.model.plant); the words of each range from fmu_config.h (generated from the
 * same tables), so a refused parameter is described as the model layer describes it.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu_model.h"
#include "plant.h"

typedef struct {
#define X(name, vr, type, start, lo, hi, lo_open, hi_open) double name;
    FP_INPUTS(X)
#undef X
} FpInputs;

typedef struct {
    FpParams p;
    FpState s;
    FpInputs in;
    int started;
} ModelData;

#define DATA(d) ((ModelData *)(d))
#define CDATA(d) ((const ModelData *)(d))

size_t model_data_size(void) { return sizeof(ModelData); }

void model_defaults(void *data) {
    ModelData *d = DATA(data);
    fp_defaults(&d->p);
#define X(name, vr, type, start, lo, hi, lo_open, hi_open) d->in.name = (start);
    FP_INPUTS(X)
#undef X
    d->started = 0;
}

static ModelType model_type(int fp_type) {
    return fp_type == FP_REAL ? MODEL_REAL : fp_type == FP_INTEGER ? MODEL_INTEGER
                                                                    : MODEL_BOOLEAN;
}

ModelCausality model_variable(fmi2ValueReference vr, ModelType *type, const char **name) {
    switch (vr) {
#define X(name_, vr_, type_, start, lo, hi, lo_open, hi_open) \
    case vr_: *type = model_type(type_); *name = #name_; return MODEL_PARAMETER;
        FP_PARAMETERS(X)
#undef X
#define X(name_, vr_, type_, start, lo, hi, lo_open, hi_open) \
    case vr_: *type = model_type(type_); *name = #name_; return MODEL_INPUT;
        FP_INPUTS(X)
#undef X
#define X(name_, vr_, type_) case vr_: *type = model_type(type_); *name = #name_; \
    return MODEL_OUTPUT;
        FP_OUTPUTS(X)
#undef X
        default: break;
    }
    *name = "";
    return MODEL_NO_VARIABLE;
}

/* Per-variable range problems only (no rules between parameters); count of them. */
static int range_problems(const FpParams *p, ModelReport report, void *context);

/* The outputs now: before the start, those of a plant started from the parameters as they
 * are (x0, v0 and the encoder), if they are valid; else x0 and v0 as given. */
static void outputs(const ModelData *d, FpOutputs *y) {
    char msg[8];
    FpState start;
    if (d->started) {
        fp_outputs(&d->s, &d->p, y);
        return;
    }
    if (range_problems(&d->p, NULL, NULL) == 0 && fp_check(&d->p, msg, sizeof msg) == 0) {
        memset(&start, 0, sizeof start);
        fp_reset(&start, &d->p);
        fp_outputs(&start, &d->p, y);
        return;
    }
    memset(y, 0, sizeof *y);
    y->x = d->p.x0;
    y->v = d->p.v0;
    y->x_meas = d->p.x0;
    y->stuck = d->p.v0 == 0.0;
}

double model_get_real(const void *data, fmi2ValueReference vr) {
    const ModelData *d = CDATA(data);
    FpOutputs y;
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) case vr_: return (double)d->p.name;
        FP_PARAMETERS(X)
#undef X
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) case vr_: return (double)d->in.name;
        FP_INPUTS(X)
#undef X
        default: break;
    }
    outputs(d, &y);
    switch (vr) {
#define X(name, vr_, type) case vr_: return (double)y.name;
        FP_OUTPUTS(X)
#undef X
        default: break;
    }
    return 0.0;
}

int model_get_integer(const void *data, fmi2ValueReference vr) {
    return (int)model_get_real(data, vr);
}

int model_get_boolean(const void *data, fmi2ValueReference vr) {
    return model_get_real(data, vr) != 0.0;
}

void model_set_real(void *data, fmi2ValueReference vr, double value) {
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) \
    case vr_: d->p.name = (type == FP_REAL) ? value : d->p.name; break;
        FP_PARAMETERS(X)
#undef X
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) case vr_: d->in.name = value; break;
        FP_INPUTS(X)
#undef X
        default: break;
    }
}

void model_set_integer(void *data, fmi2ValueReference vr, int value) {
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) \
    case vr_: if (type == FP_INTEGER) d->p.name = value; break;
        FP_PARAMETERS(X)
#undef X
        default: break;
    }
}

void model_set_boolean(void *data, fmi2ValueReference vr, int value) {
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) \
    case vr_: if (type == FP_BOOLEAN) d->p.name = (value != 0); break;
        FP_PARAMETERS(X)
#undef X
        default: break;
    }
}

/* FrictionPlant has no String variable (model_variable never names one). */
const char *model_get_string(const void *data, fmi2ValueReference vr) {
    (void)data;
    (void)vr;
    return "";
}

void model_set_string(void *data, fmi2ValueReference vr, const char *value) {
    (void)data;
    (void)vr;
    (void)value;
}

/* "<unit suffix>" and "<what is allowed>" of parameter vr (fmu_config.h). */
static void parameter_words(fmi2ValueReference vr, const char **unit, const char **allowed) {
    *unit = "";
    *allowed = "be in its range";
    switch (vr) {
#define X(vr_, unit_, allowed_) case vr_: *unit = unit_; *allowed = allowed_; break;
        FMU_PARAMETER_WORDS(X)
#undef X
        default: break;
    }
}

static void report_range(ModelReport report, void *context, const char *name,
                         fmi2ValueReference vr, int type, double value, int finite) {
    char text[48], message[512];
    const char *unit, *allowed;
    parameter_words(vr, &unit, &allowed);
    if (type == FP_REAL) fmu_format_real(value, text, sizeof text);
    else if (type == FP_INTEGER) snprintf(text, sizeof text, "%d", (int)value);
    else snprintf(text, sizeof text, "%s", value != 0.0 ? "True" : "False");
    snprintf(message, sizeof message, "parameter %s = %s%s: must %s", name, text,
             type == FP_REAL ? unit : "", finite ? allowed : "be a finite number");
    report(context, message);
}

static int range_problems(const FpParams *p, ModelReport report, void *context) {
    int count = 0;
    double value;
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open) \
    value = (double)p->name; \
    if (!isfinite(value) || ((lo_open) ? value <= (lo) : value < (lo)) || \
        ((hi_open) ? value >= (hi) : value > (hi))) { \
        count++; \
        if (report != NULL) report_range(report, context, #name, vr_, type, value, \
                                         isfinite(value)); \
    }
    FP_PARAMETERS(X)
#undef X
    return count;
}

int model_check(const void *data, ModelReport report, void *context) {
    const ModelData *d = CDATA(data);
    char msg[512], message[540];
    int count = range_problems(&d->p, report, context);
    if (count == 0 && fp_check(&d->p, msg, sizeof msg) != 0) {
        snprintf(message, sizeof message, "parameter %s", msg);
        report(context, message);
        count = 1;
    }
    return count;
}

void model_start(void *data) {
    ModelData *d = DATA(data);
    memset(&d->s, 0, sizeof d->s);
    fp_reset(&d->s, &d->p);
    d->started = 1;
}

int model_step(void *data, double h, char *msg, size_t len) {
    ModelData *d = DATA(data);
    return fp_step(&d->s, &d->p, d->in.u, h, msg, len);
}

typedef struct {
    char first[512];
} FirstProblem;

static void keep_first(void *context, const char *message) {
    FirstProblem *found = (FirstProblem *)context;
    if (found->first[0] == '\0') snprintf(found->first, sizeof found->first, "%s", message);
}

int model_state_check(const void *data, int started, char *msg, size_t len) {
    const ModelData *d = CDATA(data);
    FirstProblem found;
    FpOutputs y;
    found.first[0] = '\0';
    if (d->started != 0 && d->started != 1) {
        snprintf(msg, len, "the state is not one of FrictionPlant (started flag %d)",
                 d->started);
        return 1;
    }
    if (d->started != started) {
        snprintf(msg, len, "the state's plant %s, its phase says it %s",
                 d->started ? "has started" : "has not started",
                 started ? "has" : "has not");
        return 1;
    }
    if (!started) return 0;
    if (model_check(data, keep_first, &found) > 0) {
        snprintf(msg, len, "its parameters are invalid: %s", found.first);
        return 1;
    }
    if (fp_state_check(&d->s, found.first, sizeof found.first) != 0) {
        snprintf(msg, len, "the state does not fit: %s", found.first);
        return 1;
    }
    fp_outputs(&d->s, &d->p, &y);
    if (!isfinite(y.x) || !isfinite(y.v)) {
        snprintf(msg, len, "its position or velocity is not finite");
        return 1;
    }
    return 0;
}

/* ---------------------------------------------------------------------------------------- */
/* The plant's own functions for a process that loads this binary (papwc's runaway check
 * replays a run's forces on the plant of the run itself, papwc.master.native_plant). One
 * table is exported, so the fp_* functions stay hidden (no symbol of the plant can be
 * interposed by a host's) and the caller can check the layout of the structs it passes:
 * their sizes and "name:TYPE" of each field in order, separated by spaces. */
typedef struct {
    int version;          /* PLANT_API_VERSION */
    size_t params_size;   /* sizeof(FpParams) */
    size_t state_size;    /* sizeof(FpState) */
    size_t outputs_size;  /* sizeof(FpOutputs) */
    const char *params;   /* the fields of FpParams */
    const char *state;    /* the fields of FpState */
    const char *outputs;  /* the fields of FpOutputs */
    void (*defaults)(FpParams *p);
    int (*check)(const FpParams *p, char *msg, size_t len);
    void (*reset)(FpState *s, const FpParams *p);
    int (*step)(FpState *s, const FpParams *p, double u, double h, char *msg, size_t len);
    int (*state_check)(const FpState *s, char *msg, size_t len);
    void (*outputs_of)(const FpState *s, const FpParams *p, FpOutputs *y);
} PlantApi;

#define PLANT_API_VERSION 1

#define FIELD_OF_VARIABLE(name, vr, type, start, lo, hi, lo_open, hi_open) #name ":" #type " "
#define FIELD_OF_OUTPUT(name, vr, type) #name ":" #type " "
#define FIELD_OF_STATE(name, type) #name ":" #type " "

static const PlantApi plant_api = {
    PLANT_API_VERSION, sizeof(FpParams), sizeof(FpState), sizeof(FpOutputs),
    FP_PARAMETERS(FIELD_OF_VARIABLE), FP_STATE_FIELDS(FIELD_OF_STATE),
    FP_OUTPUTS(FIELD_OF_OUTPUT),
    fp_defaults, fp_check, fp_reset, fp_step, fp_state_check, fp_outputs,
};

FMI2_Export const PlantApi *papwc_plant_api(void);

const PlantApi *papwc_plant_api(void) { return &plant_api; }
