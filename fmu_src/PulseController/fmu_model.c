/* fmu_model.c: the C controller (controller.c) bound to the FMI glue (fmu_src/fmi2/fmi2_cs.c).
 *
 * PulseController.fmu, native: the kinds pwc, papwc and pid (the others are in
 * PulseControllerPython.fmu, the pythonfmu build). The variables are those of
 * papwc.model.controller_settings.PULSE_CONTROLLER_VARIABLES, value references and ranges
 * from controller_vars.h, so an SSP or a host that sets them by name drives either build
 * alike. The model data is the parameters, the inputs, the force and the controller: plain
 * data, so an FMU state is a copy of it. What the pythonfmu build does at each call
 * (PulseControllerPython.py) is done here in the same order with the same words:
 *
 * - the kind is the String kind or the Integer kind_code (kind_from_code); both set must
 *   name the same kind;
 * - fmi2ExitInitializationMode checks the parameters (pc_check's words) and makes the
 *   controller (pc_init);
 * - fmi2DoStep(t, h) refuses with fmi2Discard a step other than T (to STEP_RTOL) and a
 *   reading or reference that is not finite; else u = pc_update(x_meas, x_ref_offset +
 *   x_ref);
 * - a change of the input maneuver starts a new maneuver (pc_reset), u = 0.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu_model.h"
#include "papwc_controller.h"

/* The longest kind name the String holds; a longer one is refused as not a kind. */
#define KIND_TEXT 32

typedef struct {
    PcSettings s;            /* the settings parameters (s.kind: see kind) */
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    double name;
    PC_FMU_PARAMETERS(X)     /* T, kind_code, x_ref_offset (kind_code as a double) */
#undef X
    char kind[KIND_TEXT];    /* the String kind, NUL-terminated */
    int32_t kind_long;       /* the String set was longer than kind holds */
    int32_t kind_set;        /* the String kind was set */
#define X(name, vr, type, start) double name;
    PC_INPUTS(X)
#undef X
    double u;                /* the force of the last step, N */
    int32_t maneuver_seen;   /* the maneuver the controller works on */
    int32_t started;
    int64_t samples;         /* steps since the start */
    PcController c;
} ModelData;

#define DATA(d) ((ModelData *)(d))
#define CDATA(d) ((const ModelData *)(d))

size_t model_data_size(void) { return sizeof(ModelData); }

void model_defaults(void *data)
{
    ModelData *d = DATA(data);
    pc_defaults(&d->s);
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) d->name = (start);
    PC_FMU_PARAMETERS(X)
#undef X
    snprintf(d->kind, sizeof d->kind, "%s", pc_kind_name(PC_KIND_DEFAULT));
    d->kind_long = 0;
    d->kind_set = 0;
#define X(name, vr, type, start) d->name = (start);
    PC_INPUTS(X)
#undef X
    d->u = 0.0;
    d->started = 0;
    d->samples = 0;
}

static ModelType model_type(int type)
{
    return type == PC_REAL ? MODEL_REAL : type == PC_INTEGER ? MODEL_INTEGER : MODEL_BOOLEAN;
}

ModelCausality model_variable(fmi2ValueReference vr, ModelType *type, const char **name)
{
    switch (vr) {
        case PC_VR_KIND: *type = MODEL_STRING; *name = "kind"; return MODEL_PARAMETER;
#define X(name_, vr_, type_, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: *type = model_type(type_); *name = #name_; return MODEL_PARAMETER;
        PC_SETTINGS(X)
        PC_FMU_PARAMETERS(X)
#undef X
#define X(name_, vr_, setting, optional, start, unit) \
    case vr_: *type = MODEL_BOOLEAN; *name = #name_; return MODEL_PARAMETER;
        PC_SWITCHES(X)
#undef X
#define X(name_, vr_, type_, start) case vr_: *type = model_type(type_); *name = #name_; \
    return MODEL_INPUT;
        PC_INPUTS(X)
#undef X
#define X(name_, vr_, type_, start) case vr_: *type = model_type(type_); *name = #name_; \
    return MODEL_OUTPUT;
        PC_OUTPUTS(X)
#undef X
        default: break;
    }
    *name = "";
    return MODEL_NO_VARIABLE;
}

/* ---- the kind ------------------------------------------------------------------------- */

/* The kind code the String names (0: none). */
static int32_t code_of(const char *kind)
{
#define X(code, name, native) if (strcmp(kind, #name) == 0) return code;
    PC_KINDS(X)
#undef X
    return 0;
}

/* The kind kind and kind_code select (controller_settings.kind_from_code): its code (0 for
 * a String that names none), and 1 if the two name different kinds. */
static int32_t kind_of(const ModelData *d, int *conflict)
{
    int32_t code = (int32_t)d->kind_code, named = d->kind_long ? 0 : code_of(d->kind);
    *conflict = 0;
    if (code == 0 || code < 1 || code > PC_N_KINDS) return named;
    if (d->kind_set && named != code) *conflict = 1;
    return code;
}

/* The kinds of PulseControllerPython.fmu only, as a message lists them: 'exact', 'dual_loop'
 * and 'hybrid' (in PC_KINDS order). */
static void python_kinds(char *out, size_t len)
{
    size_t used = 0;
    int total = 0, n = 0;
    out[0] = '\0';
#define X(code, name, native) total += !(native);
    PC_KINDS(X)
#undef X
#define X(code, name, native) \
    if (!(native) && used + 16 < len) { \
        n++; \
        used += (size_t)snprintf(out + used, len - used, "%s'%s'", \
                                 n == 1 ? "" : n == total ? " and " : ", ", #name); \
    }
    PC_KINDS(X)
#undef X
}

/* Each problem of the kind; how many (0 or 1). */
static int kind_problem(const ModelData *d, ModelReport report, void *context)
{
    char message[512], others[128], shown[KIND_TEXT + 8];
    int conflict;
    int32_t kind = kind_of(d, &conflict);
    snprintf(shown, sizeof shown, "%s%s", d->kind, d->kind_long ? "..." : "");
    if (conflict) {
        snprintf(message, sizeof message, "parameter kind = '%s' and kind_code = %d ('%s') name "
                 "different controllers: set only one of them, or both alike", shown,
                 (int)d->kind_code, pc_kind_name(kind));
    } else if (!pc_kind_native(kind)) {
        python_kinds(others, sizeof others);
        snprintf(message, sizeof message, "parameter kind = '%s': must be one of 'papwc', 'pid', "
                 "'pwc' (PulseController.fmu is the C controller; %s are in "
                 "PulseControllerPython.fmu, which papwc build makes beside it)",
                 kind ? pc_kind_name(kind) : shown, others);
    } else {
        return 0;
    }
    if (report != NULL) report(context, message);
    return 1;
}

/* The settings with the kind in use (the default kind if none is: its problem is told). */
static PcSettings settings_of(const ModelData *d)
{
    PcSettings s = d->s;
    int conflict;
    int32_t kind = kind_of(d, &conflict);
    s.kind = pc_kind_native(kind) && !conflict ? kind : PC_KIND_DEFAULT;
    return s;
}

/* ---- values --------------------------------------------------------------------------- */

/* Per-variable range problems of the FMU's own Integer and Real parameters but T. */
static int own_problems(const ModelData *d, ModelReport report, void *context)
{
    char text[48], message[512];
    int count = 0;
    double value;
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    value = d->name; \
    if (strcmp(#name, "T") != 0 && \
        (!isfinite(value) || ((lo_open) ? value <= (lo) : value < (lo)) || \
         ((hi_open) ? value >= (hi) : value > (hi)))) { \
        count++; \
        if (type == PC_INTEGER) snprintf(text, sizeof text, "%d", (int)value); \
        else fmu_format_real(value, text, sizeof text); \
        snprintf(message, sizeof message, "parameter %s = %s%s: must %s", #name, text, unit, \
                 isfinite(value) ? words : "be a finite number"); \
        if (report != NULL) report(context, message); \
    }
    PC_FMU_PARAMETERS(X)
#undef X
    return count;
}

int model_check(const void *data, ModelReport report, void *context)
{
    const ModelData *d = CDATA(data);
    PcSettings s = settings_of(d);
    int count = kind_problem(d, report, context);
    count += pc_check_ranges(&s, d->T, (PcReport)report, context, fmu_format_real);
    count += own_problems(d, report, context);
    count += pc_check_rules(&s, d->T, (PcReport)report, context, fmu_format_real);
    return count;
}

/* The outputs now: the controller's, or before the start those of a controller made from
 * the parameters as they are (NaN estimates, Integers at their starts, if they make none). */
static void outputs(const ModelData *d, PcOutputs *y)
{
    PcController fresh;
    PcSettings s;
    if (d->started) {
        pc_outputs(&d->c, y);
        return;
    }
    s = settings_of(d);
    if (model_check(d, NULL, NULL) == 0 && pc_init(&fresh, &s, d->T) == 0) {
        pc_outputs(&fresh, y);
        return;
    }
#define X(name, vr, type, start) y->name = type == PC_REAL ? NAN : (start);
    PC_OUTPUT_FIELDS(X)
#undef X
}

double model_get_real(const void *data, fmi2ValueReference vr)
{
    const ModelData *d = CDATA(data);
    PcOutputs y;
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: return (double)d->s.name;
        PC_SETTINGS(X)
#undef X
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: return d->name;
        PC_FMU_PARAMETERS(X)
#undef X
#define X(name, vr_, setting, optional, start, unit) case vr_: return (double)d->s.name;
        PC_SWITCHES(X)
#undef X
#define X(name, vr_, type, start) case vr_: return d->name;
        PC_INPUTS(X)
#undef X
        case PC_VR_U: return d->u;
        default: break;
    }
    outputs(d, &y);
    switch (vr) {
#define X(name, vr_, type, start) case vr_: return (double)y.name;
        PC_OUTPUT_FIELDS(X)
#undef X
        default: break;
    }
    return 0.0;
}

int model_get_integer(const void *data, fmi2ValueReference vr)
{
    return (int)model_get_real(data, vr);
}

int model_get_boolean(const void *data, fmi2ValueReference vr)
{
    return model_get_real(data, vr) != 0.0;
}

const char *model_get_string(const void *data, fmi2ValueReference vr)
{
    (void)vr;
    return CDATA(data)->kind;
}

void model_set_real(void *data, fmi2ValueReference vr, double value)
{
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: if (type == PC_REAL) d->s.name = value; break;
        PC_SETTINGS(X)
#undef X
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: if (type == PC_REAL) d->name = value; break;
        PC_FMU_PARAMETERS(X)
#undef X
#define X(name, vr_, type, start) case vr_: if (type == PC_REAL) d->name = value; break;
        PC_INPUTS(X)
#undef X
        default: break;
    }
}

/* The input maneuver: a new number starts a new maneuver from rest (estimates kept). */
static void set_maneuver(ModelData *d, int value)
{
    d->maneuver = value;
    if (d->started && value != d->maneuver_seen) {
        pc_reset(&d->c);
        d->maneuver_seen = value;
        d->u = 0.0;
    }
}

void model_set_integer(void *data, fmi2ValueReference vr, int value)
{
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: if (type == PC_INTEGER) d->s.name = value; break;
        PC_SETTINGS(X)
#undef X
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: if (type == PC_INTEGER) d->name = value; break;
        PC_FMU_PARAMETERS(X)
#undef X
        case PC_VR_MANEUVER: set_maneuver(d, value); break;
        default: break;
    }
}

void model_set_boolean(void *data, fmi2ValueReference vr, int value)
{
    ModelData *d = DATA(data);
    switch (vr) {
#define X(name, vr_, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    case vr_: if (type == PC_BOOLEAN) d->s.name = (value != 0); break;
        PC_SETTINGS(X)
#undef X
#define X(name, vr_, setting, optional, start, unit) case vr_: d->s.name = (value != 0); break;
        PC_SWITCHES(X)
#undef X
        default: break;
    }
}

void model_set_string(void *data, fmi2ValueReference vr, const char *value)
{
    ModelData *d = DATA(data);
    (void)vr;
    snprintf(d->kind, sizeof d->kind, "%s", value);
    d->kind_long = strlen(value) >= sizeof d->kind;
    d->kind_set = 1;
}

/* ---- start, step, state --------------------------------------------------------------- */

void model_start(void *data)
{
    ModelData *d = DATA(data);
    PcSettings s = settings_of(d);
    snprintf(d->kind, sizeof d->kind, "%s", pc_kind_name(s.kind));
    d->kind_long = 0;
    memset(&d->c, 0, sizeof d->c);
    pc_init(&d->c, &s, d->T); /* the parameters were checked */
    d->maneuver_seen = (int32_t)d->maneuver;
    d->u = 0.0;
    d->samples = 0;
    d->started = 1;
}

int model_step(void *data, double h, char *msg, size_t len)
{
    ModelData *d = DATA(data);
    char a[48], b[48];
    double T = d->T, x_ref = d->x_ref;
    if (!(fabs(h - T) <= PC_STEP_RTOL * T)) {
        fmu_format_real(h, a, sizeof a);
        fmu_format_real(T, b, sizeof b);
        snprintf(msg, len, "the communication step size %s s differs from the sample period "
                 "T = %s s; the controller samples only at period T, so every communication "
                 "step must be T", a, b);
        return 1;
    }
    if (!isfinite(d->x_meas)) {
        fmu_format_real(d->x_meas, a, sizeof a);
        snprintf(msg, len, "input x_meas = %s m is not finite", a);
        return 1;
    }
    if (!isfinite(d->x_ref)) {
        fmu_format_real(d->x_ref, a, sizeof a);
        snprintf(msg, len, "input x_ref = %s m is not finite", a);
        return 1;
    }
    if (d->x_ref_offset != 0.0) {
        x_ref = d->x_ref_offset + d->x_ref;
        if (!isfinite(x_ref)) {
            fmu_format_real(d->x_ref_offset, a, sizeof a);
            fmu_format_real(d->x_ref, b, sizeof b);
            snprintf(msg, len, "the reference x_ref_offset + x_ref = %s + %s m is not finite",
                     a, b);
            return 1;
        }
    }
    d->u = pc_update(&d->c, (double)d->samples * T, d->x_meas, x_ref);
    d->samples += 1;
    return 0;
}

/* Whether two settings hold the same values, field by field (not their padding bytes). */
static int same_settings(const PcSettings *a, const PcSettings *b)
{
    if (a->kind != b->kind) return 0;
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    if (!(a->name == b->name)) return 0;
    PC_SETTINGS(X)
#undef X
#define X(name, vr, setting, optional, start, unit) if (a->name != b->name) return 0;
    PC_SWITCHES(X)
#undef X
    return 1;
}

int model_state_check(const void *data, int started, char *msg, size_t len)
{
    const ModelData *d = CDATA(data);
    PcSettings s;
    char why[256];
    if (d->started != 0 && d->started != 1) {
        snprintf(msg, len, "the state is not one of PulseController (started flag %d)",
                 (int)d->started);
        return 1;
    }
    if (d->started != started) {
        snprintf(msg, len, "the state's controller %s, its phase says it %s",
                 d->started ? "has started" : "has not started", started ? "has" : "has not");
        return 1;
    }
    if (memchr(d->kind, '\0', sizeof d->kind) == NULL) {
        snprintf(msg, len, "the state's kind is not a string");
        return 1;
    }
    if (!started) return 0;
    if (model_check(data, NULL, NULL) > 0) {
        snprintf(msg, len, "its parameters are invalid");
        return 1;
    }
    s = settings_of(d);
    if (pc_state_check(&d->c, why, sizeof why) != 0) {
        snprintf(msg, len, "the controller state does not fit: %s", why);
        return 1;
    }
    if (!same_settings(&s, &d->c.settings) || d->c.cfg.T != d->T) {
        snprintf(msg, len, "the controller state does not fit: it was made from other "
                 "parameters than the state's");
        return 1;
    }
    if (!isfinite(d->u) || d->samples < 0) {
        snprintf(msg, len, "its force or sample count is out of range");
        return 1;
    }
    return 0;
}
