/* controller.c: the pulse controllers of papwc in C (see papwc_controller.h).
 *
 * Each function below is the method of the Python class named in its comment, written with
 * the same operations in the same order, so that the same doubles come out: Python floats
 * are IEEE doubles; math.sqrt, math.ceil, math.floor, math.copysign, math.exp and x ** y
 * (the C library's pow) map to their C functions (the same libm in one process); a Python
 * int that counts samples is an int64_t here (no count reaches 2^63; a // b of counts >= 0
 * is a / b, a % m is py_mod); min(a, b) and max(a, b) keep the first argument unless the
 * second is smaller (larger), as Python's do, also with a NaN (py_min, py_max).
 */
#include "papwc_controller.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define PC_PI 3.141592653589793
/* n_max of an unbounded pulse width (base.py: 1 << 30). */
#define PC_N_UNBOUNDED ((int64_t)1 << 30)
/* The precision a law asks of the error before a move (PulseControllerBase.precision). */
#define PC_PRECISION 0.1

/* ---- Python's min, max, ** ------------------------------------------------------------- */

static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }
static int64_t i_min(int64_t a, int64_t b) { return b < a ? b : a; }
static int64_t i_max(int64_t a, int64_t b) { return b > a ? b : a; }
/* a % m as Python computes it for m > 0: never negative */
static int64_t py_mod(int64_t a, int64_t m)
{
    int64_t r = a % m;
    return r < 0 ? r + m : r;
}

/* x ** y as Python computes it: the C library's pow. The exponent is read through a
 * volatile so that no compiler turns pow(x, 2.0) into x*x: glibc's pow(x, 2.0) differs
 * from x*x in about one square in 1200 (the last bit), and Python calls pow. */
static double py_pow(double x, double y)
{
    volatile double exponent = y;
    return pow(x, exponent);
}

/* ---- kinds ---------------------------------------------------------------------------- */

const char *pc_kind_name(int32_t kind)
{
    switch (kind) {
#define X(code, name, native) case code: return #name;
        PC_KINDS(X)
#undef X
        default: return "";
    }
}

int pc_kind_native(int32_t kind)
{
    switch (kind) {
#define X(code, name, native) case code: return native;
        PC_KINDS(X)
#undef X
        default: return 0;
    }
}

void pc_defaults(PcSettings *s)
{
    memset(s, 0, sizeof *s);
    s->kind = PC_KIND_DEFAULT;
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) s->name = (start);
    PC_SETTINGS(X)
#undef X
}

/* ---- settings: ranges and rules ------------------------------------------------------- */

static void format_default(double value, char *out, size_t len)
{
    snprintf(out, len, "%.17g", value);
}

typedef struct {
    PcReport report;
    void *context;
    PcFormat format;
    int count;
} Problems;

static void problem(Problems *p, const char *message)
{
    p->count++;
    if (p->report != NULL) p->report(p->context, message);
}

/* The value of a setting as the model layer reads it (switched_values): NAN for a
 * computed default (None), INFINITY for no bound. */
static double t_p_max_of(const PcSettings *s) { return s->t_p_max_given ? s->t_p_max : INFINITY; }

/* "; <switch> = false selects the default" (no bound) for a setting with a switch. */
static const char *switch_words(const char *name)
{
#define X(sw, vr, setting, optional, start, unit) \
    if (strcmp(name, #setting) == 0) \
        return (optional) ? "; " #sw " = false selects the default" \
                          : "; " #sw " = false selects no bound";
    PC_SWITCHES(X)
#undef X
    return "";
}

static int switch_on(const PcSettings *s, const char *name)
{
#define X(sw, vr, setting, optional, start, unit) \
    if (strcmp(name, #setting) == 0) return s->sw != 0;
    PC_SWITCHES(X)
#undef X
    return 1;
}

/* A setting out of its range: "parameter <name> = <value><unit>: must <words>". */
static void range_problem(Problems *p, const char *name, int type, double value,
                          int inf_ok, const char *unit, const char *words)
{
    char text[48], message[512];
    if (type == PC_INTEGER) snprintf(text, sizeof text, "%d", (int)value);
    else p->format(value, text, sizeof text);
    if (isnan(value) || (isinf(value) && !(inf_ok && value > 0))) {
        snprintf(message, sizeof message, "parameter %s = %s%s: must be a finite number%s%s",
                 name, text, unit, inf_ok ? " or inf" : "", switch_words(name));
    } else {
        snprintf(message, sizeof message, "parameter %s = %s%s: must %s%s", name, text, unit,
                 words, switch_words(name));
    }
    problem(p, message);
}

static int out_of_range(double value, double lo, double hi, int lo_open, int hi_open,
                        int inf_ok)
{
    if (isnan(value)) return 1;
    if (isinf(value)) return !(inf_ok && value > 0);
    return (lo_open ? value <= lo : value < lo) || (hi_open ? value >= hi : value > hi);
}

/* A Real set away from its start while its switch is false (variables.switch_conflicts). */
static void conflict_problem(Problems *p, const char *name, const char *sw, double value,
                             double start, int optional, const char *unit)
{
    char given[48], kept[48], message[640];
    p->format(value, given, sizeof given);
    p->format(start, kept, sizeof kept);
    snprintf(message, sizeof message, "parameter %s = %s%s is not read while %s = false (%s is "
             "%s): set %s = true to use it, or leave %s at its start value %s", name, given,
             unit, sw, name, optional ? "computed" : "inf (no bound)", sw, name, kept);
    problem(p, message);
}

/* Whether setting name holds a value of its own (not switched to its default). */
static int conflicted(const PcSettings *s, const char *name)
{
#define X(sw, vr, setting, optional, start, unit) \
    if (strcmp(name, #setting) == 0) \
        return !s->sw && s->setting != (double)(start) && ((optional) || s->setting != INFINITY);
    PC_SWITCHES(X)
#undef X
    return 0;
}

int pc_check_ranges(const PcSettings *s, double T, PcReport report, void *context,
                    PcFormat format)
{
    Problems p;
    p.report = report;
    p.context = context;
    p.format = format != NULL ? format : format_default;
    p.count = 0;
#define X(sw, vr, setting, optional, start, unit) \
    if (conflicted(s, #setting)) \
        conflict_problem(&p, #setting, #sw, s->setting, (double)(start), optional, unit);
    PC_SWITCHES(X)
#undef X
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    if (type != PC_BOOLEAN && switch_on(s, #name) && !conflicted(s, #name) && \
        out_of_range((double)s->name, lo, hi, lo_open, hi_open, inf_ok)) \
        range_problem(&p, #name, type, (double)s->name, inf_ok, unit, words);
    PC_SETTINGS(X)
#undef X
#define X(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    if (strcmp(#name, "T") == 0 && out_of_range(T, lo, hi, lo_open, hi_open, inf_ok)) \
        range_problem(&p, #name, type, T, inf_ok, unit, words);
    PC_FMU_PARAMETERS(X)
#undef X
    return p.count;
}

/* Whether a setting and T passed their own checks (a rule is checked only then). */
static int valid(const PcSettings *s, const char *name, double value, double T)
{
    (void)T;
#define X(name_, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    if (strcmp(name, #name_) == 0) \
        return !conflicted(s, name) && (!switch_on(s, name) || \
            !out_of_range(value, lo, hi, lo_open, hi_open, inf_ok));
    PC_SETTINGS(X)
    PC_FMU_PARAMETERS(X)
#undef X
    return 1;
}

int pc_check_rules(const PcSettings *s, double T, PcReport report, void *context,
                   PcFormat format)
{
    Problems p;
    char a[48], b[48], c[48], message[768];
    double t_p_max = t_p_max_of(s);
    int t_ok = valid(s, "T", T, T);
    p.report = report;
    p.context = context;
    p.format = format != NULL ? format : format_default;
    p.count = 0;
    /* controller_settings.CONTROLLER_CONSTRAINTS, in their order */
    if (valid(s, "f_c_est", s->f_c_est, T) && valid(s, "f_p_max", s->f_p_max, T) &&
        !(s->f_c_est < s->f_p_max)) {
        p.format(s->f_c_est, a, sizeof a);
        p.format(s->f_p_max, b, sizeof b);
        snprintf(message, sizeof message, "parameter f_c_est = %s N: must satisfy 0 < f_c_est "
                 "< f_p_max = %s N", a, b);
        problem(&p, message);
    }
    if (s->f_p_min_given && valid(s, "f_p_min", s->f_p_min, T) &&
        valid(s, "f_p_max", s->f_p_max, T) && !(s->f_p_min <= s->f_p_max)) {
        p.format(s->f_p_min, a, sizeof a);
        p.format(s->f_p_max, b, sizeof b);
        snprintf(message, sizeof message, "parameter f_p_min = %s N: must satisfy 0 <= f_p_min "
                 "<= f_p_max = %s N%s", a, b, switch_words("f_p_min"));
        problem(&p, message);
    }
    if (valid(s, "e_band", s->e_band, T) && valid(s, "tolerance", s->tolerance, T) &&
        !(s->e_band > s->tolerance)) {
        p.format(s->e_band, a, sizeof a);
        p.format(s->tolerance, b, sizeof b);
        snprintf(message, sizeof message, "parameter e_band = %s m: must be > tolerance = %s m",
                 a, b);
        problem(&p, message);
    }
    if (valid(s, "t_p_max", t_p_max, T) && t_ok && !(t_p_max >= T)) {
        p.format(t_p_max, a, sizeof a);
        p.format(T, b, sizeof b);
        snprintf(message, sizeof message, "parameter t_p_max = %s s: must be >= T = %s s (a "
                 "pulse lasts a whole number of samples, at least one)%s", a, b,
                 switch_words("t_p_max"));
        problem(&p, message);
    }
    if (valid(s, "f_mode", s->f_mode, T) && t_ok &&
        !(s->f_mode == 0.0 || PC_MODE_PERIODS <= PC_DWELL_MAX * s->f_mode * T)) {
        p.format(s->f_mode, a, sizeof a);
        p.format(T, b, sizeof b);
        snprintf(message, sizeof message, "parameter f_mode = %s Hz: a rest lasts "
                 PC_MODE_PERIODS_TEXT " periods of it, more than %d samples of T = %s s; must "
                 "be 0 (no mode) or >= %g Hz", a, (int)PC_DWELL_MAX, b,
                 PC_MODE_PERIODS / (PC_DWELL_MAX * T));
        problem(&p, message);
    }
    if (valid(s, "f_mode", s->f_mode, T) && t_ok &&
        !(s->f_mode * T <= PC_F_MODE_MAX_T * (1.0 + 1e-12))) {
        p.format(s->f_mode, a, sizeof a);
        p.format(T, b, sizeof b);
        snprintf(c, sizeof c, "%g", PC_F_MODE_MAX_T / T);
        snprintf(message, sizeof message, "parameter f_mode = %s Hz: above " PC_F_MODE_MAX_T_TEXT
                 "/T = %s Hz (T = %s s), too close to the sampling's Nyquist frequency %g Hz for "
                 "a controller sampling at T (a motor loop cannot damp it, pulses cannot wait it "
                 "out); must be 0 (rigid or unknown) or f_mode <= " PC_F_MODE_MAX_T_TEXT
                 "/T = %s Hz (or sample faster)", a, c, b, 0.5 / T, c);
        problem(&p, message);
    }
    return p.count;
}

int pc_check(const PcSettings *s, double T, PcReport report, void *context, PcFormat format)
{
    char message[160];
    int count = 0;
    if (!pc_kind_native(s->kind)) {
        snprintf(message, sizeof message, "parameter kind = %d (%s): the C controller "
                 "implements pwc (%d), papwc (%d) and pid (%d)", (int)s->kind,
                 pc_kind_name(s->kind)[0] ? pc_kind_name(s->kind) : "no kind", PC_KIND_PWC,
                 PC_KIND_PAPWC, PC_KIND_PID);
        if (report != NULL) report(context, message);
        count = 1;
    }
    return count + pc_check_ranges(s, T, report, context, format) +
           pc_check_rules(s, T, report, context, format);
}

/* ---- rest detection (rest.py, RestDetector) ------------------------------------------- */

/* RestDetector.update_test */
static void rest_update_test(const PcConfig *cfg, PcRest *r)
{
    double band = cfg->rest_band;
    int64_t dwell = cfg->rest_samples;
    if (cfg->automatic) {
        if (r->sigma2 > 0.0) {
            band = py_max(band, PC_BAND_SIGMAS * sqrt(r->sigma2));
            dwell = i_max(dwell, PC_NOISE_DWELL);
        }
        dwell = i_max(dwell, cfg->mode_samples);
    }
    dwell = i_max(dwell, r->ring_dwell);
    r->band = band;
    r->dwell = dwell;
}

/* RestDetector.forget_direction */
static void rest_forget_direction(PcRest *r)
{
    r->dir = 0.0;
    r->turns = 0;
    r->x_turn = 0.0;
    r->legs = 0;
    r->since_force = 0;
    r->since_turn = 0;
}

/* RestDetector.reset */
static void rest_reset(PcRest *r)
{
    int i;
    r->anchor = NAN;
    r->lo = r->hi = 0.0;
    r->sum = r->sum2 = 0.0;
    r->n = 0;
    r->look = 0;
    for (i = 0; i < PC_NOISE_WINDOW; i++) r->ring[i] = 0.0;
    r->ring_n = 0;
    rest_forget_direction(r);
}

/* RestDetector.start_run */
static void rest_start_run(PcRest *r, double x)
{
    r->anchor = x;
    r->lo = r->hi = x;
    r->sum = r->sum2 = 0.0;
    r->n = 1;
    r->look = 0;
}

/* RestDetector.add_noise */
static void rest_add_noise(const PcConfig *cfg, PcRest *r, double var)
{
    r->noise_rests = i_min(r->noise_rests + 1, PC_NOISE_MEMORY);
    r->sigma2 += (var - r->sigma2) / (double)r->noise_rests;
    rest_update_test(cfg, r);
}

/* RestDetector.end_run */
static void rest_end_run(const PcConfig *cfg, PcRest *r, int force_free)
{
    int64_t n = r->n;
    double mean, var;
    if (n > PC_NOISE_DWELL && r->sum2 > 0.0 && cfg->automatic && force_free) {
        mean = r->sum / (double)n;
        var = py_max(r->sum2 / (double)n - mean * mean, 0.0) * (double)n / (double)(n - 1);
        rest_add_noise(cfg, r, var);
    }
}

/* RestDetector.read */
static int rest_read(const PcConfig *cfg, PcRest *r, double x, int force_free)
{
    double lo = r->lo, hi = r->hi, dev;
    if (x == r->anchor && lo == hi) {
        r->n += 1;
        return r->n > r->dwell;
    }
    if (x < lo) lo = x;
    if (x > hi) hi = x;
    if (hi - lo > r->band) {
        if (r->n > PC_NOISE_DWELL && r->sum2 > 0.0) rest_end_run(cfg, r, force_free);
        rest_start_run(r, x);
        return 0;
    }
    r->lo = lo;
    r->hi = hi;
    dev = x - r->anchor;
    r->sum += dev;
    r->sum2 += dev * dev;
    r->n += 1;
    return r->n > r->dwell;
}

/* RestDetector.x_hat */
static double rest_x_hat(const PcRest *r)
{
    if (r->sum == 0.0) return r->anchor;
    return r->anchor + r->sum / (double)r->n;
}

/* RestDetector.sigma_mean */
static double rest_sigma_mean(const PcRest *r) { return sqrt(r->sigma2 / (double)r->n); }

/* RestDetector.sigma_move */
static double rest_sigma_move(const PcRest *r)
{
    return sqrt(2.0 * r->sigma2 / (double)i_max(r->dwell + 1, 1));
}

/* RestDetector._turned_back */
static void rest_turned_back(const PcConfig *cfg, PcRest *r, double x)
{
    int64_t period, dwell;
    if (fabs(x - r->x_turn) <= py_max(PC_RING_LEG, r->band)) return;
    r->legs = 1;
    if (cfg->automatic) {
        period = i_min(r->since_force, 4 * (r->since_turn + 1));
        dwell = i_min((int64_t)ceil(PC_RING_PERIODS * (double)i_max(period, 2)),
                      PC_RING_DWELL_MAX);
        if (dwell > r->ring_dwell) {
            r->ring_dwell = dwell;
            rest_update_test(cfg, r);
        }
    }
}

/* RestDetector.quiet_window */
static int rest_quiet_window(const PcConfig *cfg, PcRest *r)
{
    const double *ring = r->ring;
    int64_t k = r->ring_n;
    double first = ring[k % PC_NOISE_WINDOW];
    double last = ring[(k - 1) % PC_NOISE_WINDOW];
    double s2 = 0.0, prev = first, x, var, lo, hi, sum, sum2;
    int i;
    for (i = 1; i < PC_NOISE_WINDOW; i++) {
        x = ring[(k + i) % PC_NOISE_WINDOW];
        s2 += py_pow(x - prev, 2.0);
        prev = x;
    }
    if (!(s2 > 0.0)) return 0;
    var = s2 / (2.0 * (PC_NOISE_WINDOW - 1));
    if (fabs(last - first) > PC_NOISE_DRIFT * sqrt(2.0 * var)) return 0;
    rest_add_noise(cfg, r, var);
    lo = hi = ring[0];
    sum = sum2 = 0.0;
    for (i = 0; i < PC_NOISE_WINDOW; i++) {
        lo = py_min(lo, ring[i]);
        hi = py_max(hi, ring[i]);
        sum += ring[i] - first;
    }
    for (i = 0; i < PC_NOISE_WINDOW; i++) sum2 += py_pow(ring[i] - first, 2.0);
    r->anchor = first;
    r->lo = lo;
    r->hi = hi;
    r->sum = sum;
    r->sum2 = sum2;
    r->n = PC_NOISE_WINDOW;
    r->look = 0;
    r->ring_n = 0;
    return 1;
}

/* RestDetector.force_free */
static int rest_force_free(const PcConfig *cfg, PcRest *r, double x, double dx, int at_rest)
{
    r->ring[r->ring_n % PC_NOISE_WINDOW] = x;
    r->ring_n += 1;
    r->since_force += 1;
    r->since_turn += 1;
    if (r->since_force == 1) r->x_turn = x - dx;
    if (dx != 0.0) {
        if (dx * r->dir < 0.0) {
            r->turns += 1;
            r->x_turn = x - dx;
            r->since_turn = 1;
        }
        r->dir = dx;
        if (r->turns && !r->legs && cfg->mode_samples == 0) rest_turned_back(cfg, r, x);
    }
    if (cfg->automatic) {
        if (at_rest && r->turns >= 2 && r->sigma2 == 0.0)
            at_rest = r->n > PC_NOISE_DWELL && r->lo == r->hi;
        if (!at_rest && r->ring_n >= PC_NOISE_WINDOW) at_rest = rest_quiet_window(cfg, r);
    }
    return at_rest;
}

/* RestDetector.count_idle */
static void rest_count_idle(PcRest *r, int64_t k, double x)
{
    int64_t i, start = r->ring_n;
    r->n += k;
    for (i = 0; i < i_min(k, PC_NOISE_WINDOW); i++) r->ring[(start + i) % PC_NOISE_WINDOW] = x;
    r->ring_n = start + k;
}

/* ---- trust region (trust.py, TrustRegion) --------------------------------------------- */

/* TrustRegion.__call__ */
static double trust_now(const PcController *c)
{
    if (!c->cfg.guarded) return 1.0;
    return (c->cfg.flexible || c->trust.ring) ? py_min(c->trust.value, PC_TRUST_FLEXIBLE)
                                                : c->trust.value;
}

/* TrustRegion.ringing */
static void trust_ringing(PcTrust *tr)
{
    tr->ring = 1;
    tr->value = py_max(PC_TRUST_MIN, tr->value * PC_TRUST_RING);
}

/* TrustRegion.judge */
static void trust_judge(PcTrust *tr, double pred, double d_along, double noise)
{
    double err, r;
    if (!(pred > 0.0 && isfinite(pred))) return;
    err = fabs(d_along - pred) - noise;
    r = py_max(err, 0.0) / pred;
    if (r <= PC_TRUST_GOOD) {
        tr->value = py_min(1.0, tr->value * PC_TRUST_GROWTH);
    } else if (d_along > pred) {
        tr->value = py_max(PC_TRUST_MIN,
                           py_min(tr->value, 1.2 * pred / py_max(d_along, 1e-300)));
    }
}

/* ---- the laws: PWC (pwc.py), PAPWC (papwc.py), PID (pid.py) --------------------------- */

static int flexible(const PcController *c) { return c->cfg.flexible || c->trust.ring; }

/* PulseControllerBase.width_samples */
static int64_t width_samples(const PcController *c, double t_p)
{
    double n;
    if (!isfinite(t_p)) return c->cfg.n_max;
    n = ceil(t_p / c->cfg.T - 1e-9);
    return n < 1 ? 1 : n > (double)c->cfg.n_max ? c->cfg.n_max : (int64_t)n;
}

/* f_low of the law (PulseControllerBase.f_low; PWC and PID: f_p_max). */
static double law_f_low(const PcController *c)
{
    if (c->cfg.kind == PC_KIND_PAPWC) return py_min(c->law.f_p_floor, c->cfg.f_p_max);
    return c->cfg.f_p_max;
}

/* The law's predict: PwcController.predict (Eq. (4)/(5)), PapwcController.predict (Eq. (4)
 * with Eq. (12)); the PID has no model (NaN). */
static double law_predict(const PcController *c, int64_t n, double f_p)
{
    double t = (double)n * c->cfg.T, f;
    if (c->cfg.kind == PC_KIND_PWC) return c->law.b_hat * t * t;
    if (c->cfg.kind == PC_KIND_PAPWC) {
        f = fabs(f_p);
        return py_max(c->law.a1 * f * f - c->law.a2 * f, 0.0) * t * t;
    }
    return NAN;
}

/* papwc.creep_prediction */
static double creep_prediction(double f_p, double eq4, const double creeps[4])
{
    double f_0 = creeps[0], d_0 = creeps[1], f_1 = creeps[2], d_1 = creeps[3];
    double far, grown, above;
    int have;
    if (!(f_1 > f_0 && f_0 > 0.0 && d_1 > d_0 && d_0 > 0.0)) {
        far = PC_FAR_LESS * py_max(d_0, d_1);
        if (!(f_0 > 0.0 && py_min(d_0, d_1) >= far && far > 0.0)) return eq4;
        have = 0;
        above = 0.0;
        if (f_0 >= f_p) {
            above = d_0;
            have = 1;
        }
        if (f_1 >= f_p) {
            above = have ? py_max(above, d_1) : d_1;
            have = 1;
        }
        return have ? py_min(eq4, py_max(PC_FAR_LESS * eq4, above)) : eq4;
    }
    grown = f_p <= f_1 ? d_1 : d_1 * py_pow(d_1 / d_0, (f_p - f_1) / (f_1 - f_0));
    return py_min(eq4, py_max(PC_FAR_LESS * eq4, grown));
}

/* The law's reach: PapwcController.reach; the others, predict. */
static double law_reach(const PcController *c, int64_t n, double f_p)
{
    double eq4 = law_predict(c, n, f_p);
    if (c->cfg.kind == PC_KIND_PAPWC && n == 1 && fabs(f_p) <= c->law.f_p_floor &&
        !flexible(c))
        return creep_prediction(fabs(f_p), eq4, c->law.creeps);
    return eq4;
}

/* PulseSequencer._farther */
static int farther(const PcController *c, double e, double after)
{
    return after > fabs(c->seq.e0) && after > fabs(e);
}

/* PulseSequencer.may_end_farther */
static int may_end_farther(const PcController *c, double e, double f_p, double pred)
{
    double step;
    if (!isfinite(pred)) return 0;
    step = copysign(pred, f_p);
    return farther(c, e, py_max(fabs(e - step),
                                fabs(e - step / py_max(trust_now(c), PC_TRUST_MIN))));
}

/* base.cut_width: the width n cut while it is too far and n > 1, one sample at a time from
 * at most PC_CUT_BY_ONE_UP_TO samples, halved above (too_far: 1 if the width is too far). */
#define CUT_WIDTH(n, too_far)                                                              \
    while ((n) > 1 && (too_far)) (n) = (n) > PC_CUT_BY_ONE_UP_TO ? (n) / 2 : (n) - 1

/* PwcController.plan_pulse (Eq. (6)) */
static int64_t pwc_plan(PcController *c, double e, double *f_p)
{
    double t_p = sqrt(c->cfg.K_c * fabs(e) / c->law.b_hat), limit;
    int64_t n;
    c->law.t_p_plan = py_min(t_p, (double)c->cfg.n_max * c->cfg.T);
    n = width_samples(c, t_p);
    if (c->cfg.guarded) {
        limit = trust_now(c) * fabs(e);
        CUT_WIDTH(n, law_predict(c, n, 1.0) > limit);
    }
    *f_p = copysign(c->cfg.f_p_max, e);
    return n;
}

/* papwc.papwc_amplitude, Eq. (11) */
static double papwc_amplitude(double f_c, double f_p, double t_p, double T_x)
{
    double radicand = f_c * f_c + 4.0 * f_p * (f_p - f_c) * py_pow(t_p / T_x, 2.0);
    return 0.5 * f_c + 0.5 * sqrt(py_max(radicand, 0.0));
}

/* PapwcController.plan_pulse's height: Eq. (11) for the width n*T, within the floor and
 * f_p_max (N) */
static double papwc_height(const PcController *c, int64_t n, double t_p, double f_c,
                           double f_max)
{
    double T_x = (double)n * c->cfg.T;
    double f_p = t_p >= T_x ? f_max : papwc_amplitude(f_c, f_max, t_p, T_x);
    return py_min(py_max(f_p, c->law.f_p_floor), f_max);
}

/* PapwcController.plan_pulse (Eq. (6) at f_p_max, Eq. (11), the floor) */
static int64_t papwc_plan(PcController *c, double e, double *f_out)
{
    double f_max = c->cfg.f_p_max, a1 = c->law.a1, a2 = c->law.a2;
    double f_c = a2 / a1, b = a1 * f_max * f_max - a2 * f_max;
    double k_c, t_p, f_p, fs[2], f, tmp, reach;
    int64_t n;
    int m = 0, i;
    c->law.f_p_plan = f_max;
    if (!(b > 0.0 && f_c > 0.0)) {
        c->law.t_p_plan = c->cfg.T;
        *f_out = copysign(f_max, e);
        return 1;
    }
    k_c = c->cfg.K_c;
    if (c->cfg.guarded) k_c = py_min(k_c, trust_now(c));
    t_p = sqrt(k_c * fabs(e) / b);
    c->law.t_p_plan = py_min(t_p, (double)c->cfg.n_max * c->cfg.T);
    n = width_samples(c, t_p);
    if (c->cfg.guarded)
        CUT_WIDTH(n, law_predict(c, n, papwc_height(c, n, t_p, f_c, f_max)) >
                         trust_now(c) * fabs(e));
    f_p = copysign(papwc_height(c, n, t_p, f_c, f_max), e);
    if (c->cfg.guarded && n == 1 && !flexible(c) &&
        may_end_farther(c, e, f_p, law_reach(c, 1, f_p))) {
        /* the creeps' own heights below the floor, highest first */
        for (i = 0; i < 4; i += 2) {
            f = c->law.creeps[i];
            if (0.0 < f && f < fabs(f_p)) fs[m++] = f;
        }
        if (m == 2 && fs[1] > fs[0]) {
            tmp = fs[0];
            fs[0] = fs[1];
            fs[1] = tmp;
        }
        for (i = 0; i < m; i++) {
            f = copysign(fs[i], e);
            reach = law_reach(c, 1, f);
            if (reach < law_predict(c, 1, f) && !may_end_farther(c, e, f, reach)) {
                *f_out = f;
                return 1;
            }
        }
    }
    *f_out = f_p;
    return n;
}

/* The law's plan_pulse; the PID refuses (height 0). */
static int64_t law_plan(PcController *c, double e, double *f_p)
{
    if (c->cfg.kind == PC_KIND_PWC) return pwc_plan(c, e, f_p);
    if (c->cfg.kind == PC_KIND_PAPWC) return papwc_plan(c, e, f_p);
    *f_p = 0.0;
    return 1;
}

/* ScalarRls.update, Eq. (7)-(9) */
static void scalar_rls_update(PcController *c, double u_p, double d)
{
    double eps = d - c->law.b_hat * u_p, F_inv = c->law.F_inv, b_new;
    if (c->cfg.update_covariance) F_inv = c->cfg.lambda_1 * F_inv + c->cfg.lambda_2 * u_p * u_p;
    if (!(isfinite(F_inv) && F_inv > 0.0) || !isfinite(eps)) return;
    c->law.F_inv = F_inv;
    b_new = c->law.b_hat + u_p * eps / F_inv;
    if (isfinite(b_new)) c->law.b_hat = py_min(py_max(b_new, c->cfg.b_min), c->cfg.b_max);
}

/* Rls2.update, Eq. (13)-(17) */
static void rls2_update(PcController *c, double phi0, double phi1, double d)
{
    PcLaw *L = &c->law;
    double p00 = L->p11, p01 = L->p12, p10 = L->p12, p11 = L->p22;
    double a0 = L->a1, a1 = L->a2, lam = c->cfg.lam;
    double pi0 = p00 * phi0 + p01 * phi1, pi1 = p10 * phi0 + p11 * phi1;
    double denom = lam + phi0 * pi0 + phi1 * pi1;
    double xi = d - (a0 * phi0 + a1 * phi1);
    double k0, k1, q00, q11, q01;
    if (!(isfinite(denom) && denom > 0.0 && isfinite(xi))) return;
    k0 = pi0 / denom;
    k1 = pi1 / denom;
    q00 = (p00 - k0 * pi0) / lam;
    q11 = (p11 - k1 * pi1) / lam;
    q01 = 0.5 * ((p01 - k0 * pi1) + (p10 - k1 * pi0)) / lam;
    a0 = a0 + k0 * xi;
    a1 = a1 + k1 * xi;
    if (!(isfinite(q00) && isfinite(q11) && isfinite(q01) && isfinite(a0) && isfinite(a1)))
        return;
    if (!c->cfg.update_covariance) {
        /* P stays P(0) */
    } else if (q00 > 0.0 && q11 > 0.0 && q00 * q11 - q01 * q01 > 0.0) {
        L->p11 = q00;
        L->p12 = q01;
        L->p22 = q11;
    } else {
        L->p11 = c->cfg.delta_inv;
        L->p12 = 0.0;
        L->p22 = c->cfg.delta_inv;
    }
    L->a1 = a0 < c->cfg.a1_min ? c->cfg.a1_min : a0 > c->cfg.a1_max ? c->cfg.a1_max : a0;
    L->a2 = a1 < c->cfg.a2_min ? c->cfg.a2_min : a1 > c->cfg.a2_max ? c->cfg.a2_max : a1;
}

/* PwcController.learn */
static void pwc_learn(PcController *c, int64_t n, double f_p, double d)
{
    double t_p;
    if (d == 0.0) return;
    t_p = c->cfg.regressor == PC_REGRESSOR_PLANNED ? c->law.t_p_plan : (double)n * c->cfg.T;
    scalar_rls_update(c, copysign(t_p * t_p, f_p), d);
}

/* PapwcController._raise_floor */
static void raise_floor(PcController *c, double f_p)
{
    c->law.f_p_floor = py_min(py_max(c->law.f_p_floor, fabs(f_p) * (1.0 + c->cfg.floor_raise)),
                              c->cfg.f_p_max);
}

/* PapwcController._keep_creep */
static void keep_creep(PcController *c, double f_p, double d_along)
{
    double *cr = c->law.creeps;
    if (PC_Z_DECIDE * rest_sigma_move(&c->rest) < d_along &&
        d_along < law_predict(c, 1, f_p)) {
        if (fabs(f_p) == cr[2]) {
            cr[3] = py_max(cr[3], d_along);
        } else {
            cr[0] = cr[2];
            cr[1] = cr[3];
            cr[2] = fabs(f_p);
            cr[3] = d_along;
        }
    } else {
        cr[0] = cr[1] = cr[2] = cr[3] = 0.0;
    }
}

/* PapwcController.learn, Eq. (13)-(18) */
static void papwc_learn(PcController *c, int64_t n, double f_p, double d)
{
    double d_along = f_p > 0.0 ? d : -d, f, t2;
    double a1, a2, b1, b2, p11, p12, p22;
    int mode;
    if (n == 1) keep_creep(c, f_p, d_along);
    if (c->cfg.guarded && d_along > 0.0 && d_along < PC_FAR_LESS * law_predict(c, n, f_p)) {
        raise_floor(c, f_p);
        return;
    }
    if (!(d_along > 0.0)) {
        mode = c->cfg.floor_mode;
        if (mode == PC_FLOOR_RAISE || mode == PC_FLOOR_RAISE_LEARN) raise_floor(c, f_p);
        if (mode == PC_FLOOR_RAISE) return;
        d_along = 0.0;
    }
    if (c->cfg.regressor == PC_REGRESSOR_PLANNED) {
        f = c->law.f_p_plan;
        t2 = py_pow(c->law.t_p_plan, 2.0);
    } else {
        f = fabs(f_p);
        t2 = py_pow((double)n * c->cfg.T, 2.0);
    }
    b1 = c->law.a1;
    b2 = c->law.a2;
    p11 = c->law.p11;
    p12 = c->law.p12;
    p22 = c->law.p22;
    rls2_update(c, f * f * t2, -f * t2, d_along);
    a1 = c->law.a1;
    a2 = c->law.a2;
    if (!(a1 > 0.0 && a2 > 0.0 && a2 / a1 < c->cfg.f_p_max)) {
        /* an estimate by which f_p_max could not move the mass is rejected */
        c->law.a1 = b1;
        c->law.a2 = b2;
        c->law.p11 = p11;
        c->law.p12 = p12;
        c->law.p22 = p22;
    }
}

static void law_learn(PcController *c, int64_t n, double f_p, double d)
{
    if (c->cfg.kind == PC_KIND_PWC) pwc_learn(c, n, f_p, d);
    else if (c->cfg.kind == PC_KIND_PAPWC) papwc_learn(c, n, f_p, d);
}

/* pid.trapezoid */
static void trapezoid(double d, double a_max, double v_max, double t, double out[3])
{
    double s = d >= 0.0 ? 1.0 : -1.0, dist = fabs(d), v_top, t_a, t_c, t_d, left;
    if (dist == 0.0 || t < 0.0) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    v_top = py_min(v_max, sqrt(dist * a_max));
    t_a = v_top / a_max;
    t_c = (dist - v_top * t_a) / v_top;
    if (t < t_a) {
        out[0] = s * 0.5 * a_max * t * t;
        out[1] = s * a_max * t;
        out[2] = s * a_max;
        return;
    }
    if (t < t_a + t_c) {
        out[0] = s * (0.5 * v_top * t_a + v_top * (t - t_a));
        out[1] = s * v_top;
        out[2] = 0.0;
        return;
    }
    t_d = t - t_a - t_c;
    if (t_d < t_a) {
        left = t_a - t_d;
        out[0] = s * (dist - 0.5 * a_max * left * left);
        out[1] = s * a_max * left;
        out[2] = -s * a_max;
        return;
    }
    out[0] = d;
    out[1] = 0.0;
    out[2] = 0.0;
}

/* PidController._profile */
static void pid_profile(const PcController *c, double out[3])
{
    double d = c->law.x_to - c->law.x_from;
    trapezoid(d, c->cfg.a_max, c->cfg.v_max, (double)c->law.k * c->cfg.T, out);
    out[0] = out[0] == d ? c->law.x_to : c->law.x_from + out[0];
}

/* PidController.reference */
static void pid_reference(PcController *c, double out[3])
{
    double x_ref = c->law.x_ref_now;
    if (x_ref != c->law.x_to) {
        pid_profile(c, out);
        c->law.x_from = out[0];
        c->law.x_to = x_ref;
        c->law.k = 0;
    }
    pid_profile(c, out);
}

/* PidController.arrived */
static int pid_arrived(PcController *c)
{
    double r[3];
    pid_reference(c, r);
    return r[1] == 0.0 && c->law.k > 0;
}

/* PidController.force */
static double pid_force(PcController *c, double x, double v)
{
    double r[3], err, f_max = c->cfg.f_p_max, fb, ff, integral, i_lim, u_lin, sign, u;
    const PcConfig *g = &c->cfg;
    pid_reference(c, r);
    err = r[0] - x;
    fb = g->pid_k_p * err + g->pid_k_d * (r[1] - v);
    ff = g->m_est * r[2];
    integral = c->law.integral + err * g->T;
    if (g->pid_k_i > 0.0) {
        i_lim = f_max / g->pid_k_i;
        integral = py_min(py_max(integral, -i_lim), i_lim);
    }
    u_lin = fb + ff + g->pid_k_i * integral;
    sign = r[1] != 0.0 ? r[1] : (!g->mode_samples ? err : 0.0);
    u = u_lin + (sign != 0.0 ? copysign(g->f_c_est, sign) : 0.0);
    if (fabs(u) > f_max && err * u > 0.0) {
        integral = c->law.integral;
        u_lin = fb + ff + g->pid_k_i * integral;
        u = u_lin + (sign != 0.0 ? copysign(g->f_c_est, sign) : 0.0);
    }
    c->law.integral = integral;
    return py_min(py_max(u, -f_max), f_max);
}

/* ---- the sequencer (sequencer.py, PulseSequencer; pid.py, PidSequencer) --------------- */

/* PulseSequencer.stop */
static double seq_stop(PcController *c, int64_t reason)
{
    PcSequencer *q = &c->seq;
    q->stopped = 1;
    q->mode = PC_MODE_SETTLED;
    q->outcome = PC_OUTCOME_STOPPED;
    q->outcome_reason = reason;
    q->pulse_left = 0;
    q->f_pulse = 0.0;
    return 0.0;
}

/* PulseSequencer.settle */
static double seq_settle(PcController *c)
{
    c->seq.mode = PC_MODE_SETTLED;
    c->seq.outcome = PC_OUTCOME_SETTLED;
    c->seq.outcome_reason = PC_REASON_WITHIN_TOLERANCE;
    return 0.0;
}

/* PulseSequencer.hand_over_band */
static double hand_over_band(const PcController *c)
{
    if (c->cfg.guarded && flexible(c)) return py_min(c->cfg.e_band, PC_E_BAND_FLEXIBLE);
    return c->cfg.e_band;
}

/* PulseSequencer.coarse; PidSequencer.coarse */
static double seq_coarse(PcController *c, double e)
{
    double u, f_max;
    rest_forget_direction(&c->rest);
    if (c->cfg.kind == PC_KIND_PID) return pid_force(c, c->seq.x_prev, c->seq.v_hat);
    u = c->cfg.k_p * e - c->cfg.k_d * c->seq.v_hat + copysign(c->cfg.f_c_est, e);
    f_max = c->cfg.f_p_max;
    return py_min(py_max(u, -f_max), f_max);
}

/* PulseSequencer._coasts_inside; PidSequencer._coasts_inside */
static int coasts_inside(PcController *c, double e)
{
    double v, d;
    if (c->cfg.kind == PC_KIND_PID) {
        if (!pid_arrived(c)) return 0;
        v = c->seq.v_hat;
        d = c->cfg.m_est * v * v / (2.0 * c->cfg.f_c_est);
        return fabs(e - copysign(d, v)) <= c->cfg.tolerance;
    }
    v = c->seq.v_hat;
    d = c->cfg.m_est * v * v / (2.0 * c->cfg.f_c_est);
    return fabs(e - copysign(d, v)) <= hand_over_band(c);
}

/* PulseSequencer._stalled */
static int stalled(PcController *c, double x, double e)
{
    PcSequencer *q = &c->seq;
    if (fabs(x - q->stall_x) > PC_STALL_BAND) {
        q->stall_x = x;
        q->stall_n = 0;
        return 0;
    }
    q->stall_n += 1;
    return q->stall_n > PC_STALL_SAMPLES && fabs(e) <= c->cfg.e_band && c->cfg.guarded &&
           flexible(c);
}

/* PulseSequencer.drive_slip */
static double drive_slip(const PcController *c, int64_t n, double f_p)
{
    double work;
    if (!c->cfg.flexible || !(c->cfg.m_d_est > 0.0) || !(c->cfg.f_c_est > 0.0)) return 0.0;
    work = py_pow(f_p * (double)n * c->cfg.T, 2.0) / (2.0 * c->cfg.m_d_est);
    return work / c->cfg.f_c_est;
}

/* PulseSequencer.may_slip_farther */
static int may_slip_farther(const PcController *c, double e, int64_t n, double f_p)
{
    double slip = drive_slip(c, n, f_p);
    return slip > 0.0 && farther(c, e, fabs(e - copysign(slip, f_p)));
}

/* PulseSequencer._ringing_pulse */
static int64_t ringing_pulse(const PcController *c, double e, double *f_p)
{
    double f_low = law_f_low(c);
    if (PC_RING_MARGIN * c->trust.d_one > PC_RUNAWAY_FACTOR * fabs(e) && 0.0 < f_low &&
        f_low < fabs(*f_p))
        *f_p = copysign(f_low, *f_p);
    return 1;
}

/* PulseSequencer.fire */
static double seq_fire(PcController *c, int64_t n, double f_p, double pred, double x_hat)
{
    PcSequencer *q = &c->seq;
    q->pred = isfinite(pred) ? pred : 0.0;
    q->mode = PC_MODE_PULSE;
    q->outcome = PC_OUTCOME_ACTIVE;
    q->outcome_reason = PC_REASON_NONE;
    q->pulses += 1;
    q->n_pulse = n;
    q->f_pulse = f_p;
    q->pulse_left = n - 1;
    q->x_start = x_hat;
    rest_start_run(&c->rest, q->x_prev);
    c->rest.ring_n = 0;
    rest_forget_direction(&c->rest);
    q->last_n = n;
    q->last_f = f_p;
    return f_p;
}

/* PulseSequencer._pulse_ended */
static void pulse_ended(PcController *c, double d)
{
    PcSequencer *q = &c->seq;
    int64_t n = q->n_pulse;
    double f_p = q->f_pulse, d_along, noise;
    q->last_d = d;
    d_along = f_p > 0.0 ? d : -d;
    noise = PC_Z_DECIDE * rest_sigma_move(&c->rest);
    trust_judge(&c->trust, q->pred, d_along, noise);
    law_learn(c, n, f_p, d);
    if (n == 1 && flexible(c)) c->trust.d_one = py_max(c->trust.d_one, fabs(d));
    q->n_pulse = 0;
}

/* PulseSequencer._decide */
static double seq_decide_base(PcController *c, double x_ref)
{
    PcSequencer *q = &c->seq;
    PcRest *r = &c->rest;
    double x_hat = rest_x_hat(r), e = x_ref - x_hat, tol = c->cfg.tolerance, s, f_p, pred;
    int64_t look, n;
    if (r->sigma2 > 0.0) {
        look = i_max(r->look, r->dwell + 1);
        if (r->n < look && (q->mode == PC_MODE_WAIT || q->mode == PC_MODE_SETTLED)) return 0.0;
        while (look <= r->n) look = (3 * look + 1) / 2;
        r->look = look;
        s = rest_sigma_mean(r);
        if (fabs(e) + PC_Z_DECIDE * s <= tol) return seq_settle(c);
        if (!(fabs(e) > py_max(tol, PC_Z_DECIDE * s) &&
              PC_Z_ACT * s <= py_max(tol, py_max(PC_PRECISION, PC_PRECISION_MIN) * fabs(e)))) {
            if (q->mode == PC_MODE_SETTLED && q->outcome == PC_OUTCOME_SETTLED) return 0.0;
            q->mode = PC_MODE_WAIT;
            return 0.0;
        }
    } else if (fabs(e) <= tol) {
        return seq_settle(c);
    }
    if (fabs(e) > c->cfg.e_band ||
        (fabs(e) > hand_over_band(c) &&
         !(q->mode == PC_MODE_COARSE && q->stall_n > PC_STALL_SAMPLES))) {
        if (q->mode != PC_MODE_COARSE) {
            q->stall_x = x_hat;
            q->stall_n = 0;
        } else if (stalled(c, q->x_prev, e)) {
            q->released = 1;
            r->ring_n = 0;
            return 0.0;
        }
        q->mode = PC_MODE_COARSE;
        q->released = 0;
        q->outcome = PC_OUTCOME_ACTIVE;
        return seq_coarse(c, x_ref - q->x_prev);
    }
    if (c->cfg.guarded && q->pulses >= c->cfg.max_pulses) return seq_stop(c, PC_REASON_PULSE_BUDGET);
    q->refusal = PC_REASON_NO_MOVE_HELPS;
    n = law_plan(c, e, &f_p);
    if (f_p == 0.0 || !isfinite(f_p)) return seq_stop(c, q->refusal);
    if (c->cfg.guarded && flexible(c)) n = ringing_pulse(c, e, &f_p);
    pred = law_predict(c, n, f_p);
    if (c->cfg.guarded && (may_end_farther(c, e, f_p, law_reach(c, n, f_p)) ||
                           may_slip_farther(c, e, n, f_p)))
        return seq_stop(c, PC_REASON_NO_MOVE_HELPS);
    return seq_fire(c, n, f_p, pred, x_hat);
}

/* PidSequencer._decide */
static double seq_decide_pid(PcController *c, double x_ref)
{
    PcSequencer *q = &c->seq;
    PcRest *r = &c->rest;
    double u, e, side;
    if (q->mode == PC_MODE_COARSE && !q->released &&
        fabs(x_ref - rest_x_hat(r)) <= c->cfg.tolerance) {
        q->released = 1;
        r->ring_n = 0;
        return 0.0;
    }
    u = seq_decide_base(c, x_ref);
    if (q->mode != PC_MODE_COARSE || !pid_arrived(c)) return u;
    e = x_ref - rest_x_hat(r);
    side = e > 0.0 ? 1.0 : -1.0;
    if (c->law.side && side != c->law.side) c->law.reversals += 1;
    c->law.side = side;
    if (c->law.reversals >= c->cfg.hunt_max && fabs(e) < fabs(q->e0))
        return seq_stop(c, PC_REASON_HUNTING);
    return u;
}

static double seq_decide(PcController *c, double x_ref)
{
    return c->cfg.kind == PC_KIND_PID ? seq_decide_pid(c, x_ref) : seq_decide_base(c, x_ref);
}

/* PulseSequencer.catch_up */
static void seq_catch_up(PcController *c)
{
    int64_t k = c->seq.idle_samples;
    c->seq.idle_samples = 0;
    rest_count_idle(&c->rest, k, c->seq.idle_x);
}

/* PulseSequencer.update */
static double seq_update(PcController *c, double x_meas, double x_ref)
{
    PcSequencer *q = &c->seq;
    PcRest *r = &c->rest;
    int64_t mode, legs;
    int at_rest, moved;
    double dx, e;
    if (x_meas == q->idle_x && x_ref == q->idle_ref) {
        q->idle_samples += 1;
        return 0.0;
    }
    if (q->idle_samples) seq_catch_up(c);
    if (q->stopped) return 0.0;
    if (!(-PC_X_LIMIT <= x_meas && x_meas <= PC_X_LIMIT && -PC_X_LIMIT <= x_ref &&
          x_ref <= PC_X_LIMIT))
        return seq_stop(c, PC_REASON_INVALID_MEASUREMENT);
    if (q->outcome == PC_OUTCOME_SETTLED && q->mode == PC_MODE_SETTLED && x_meas == r->anchor &&
        r->lo == r->hi && r->sigma2 == 0.0 && r->n >= r->dwell && r->n >= PC_NOISE_DWELL &&
        fabs(x_ref - x_meas) <= c->cfg.tolerance) {
        /* settled and the reading unchanged: the steps below would only count it */
        r->n += 1;
        q->v_hat = 0.0;
        q->x_prev = x_meas;
        r->ring[r->ring_n % PC_NOISE_WINDOW] = x_meas;
        r->ring_n += 1;
        q->idle_x = x_meas;
        q->idle_ref = x_ref;
        return 0.0;
    }
    q->idle_x = NAN;
    mode = q->mode;
    if (q->first) {
        at_rest = 1;
        q->first = 0;
        q->v_hat = 0.0;
        rest_start_run(r, x_meas);
        q->e0 = x_ref - x_meas;
        dx = 0.0;
    } else {
        dx = x_meas - q->x_prev;
        q->v_hat = dx / c->cfg.T;
        at_rest = rest_read(&c->cfg, r, x_meas,
                            mode != PC_MODE_PULSE && (mode != PC_MODE_COARSE || q->released));
    }
    q->x_prev = x_meas;

    if (q->pulse_left > 0) {
        q->pulse_left -= 1;
        return q->f_pulse;
    }
    if (mode != PC_MODE_COARSE || q->released) {
        legs = r->legs;
        at_rest = rest_force_free(&c->cfg, r, x_meas, dx, at_rest);
        if (r->legs > legs && c->cfg.guarded) trust_ringing(&c->trust);
    }
    if (mode == PC_MODE_PULSE) {
        q->mode = mode = PC_MODE_WAIT;
        q->waited = 0;
    }
    if (mode == PC_MODE_WAIT) {
        q->waited += 1;
        if (q->n_pulse > 0) {
            moved = fabs(x_meas - q->x_start) > r->band;
            if (!at_rest || (!moved && q->waited <= r->dwell)) return 0.0;
            pulse_ended(c, rest_x_hat(r) - q->x_start);
        } else if (!at_rest) {
            return 0.0;
        }
    } else if (!at_rest) {
        if (mode == PC_MODE_SETTLED) return 0.0;
        e = x_ref - x_meas;
        if (q->released) return 0.0;
        if ((fabs(e) <= hand_over_band(c) && coasts_inside(c, e)) || stalled(c, x_meas, e)) {
            q->released = 1;
            r->ring_n = 0;
            return 0.0;
        }
        return seq_coarse(c, e);
    }
    return seq_decide(c, x_ref);
}

/* ---- the PID's in-position window (pid.py, PidSequencer.window_update) --------------- */

/* pid.rounding_bias: the largest bias of the mean of readings rounded to the count q (m)
 * under encoder noise of variance sigma2 (m^2), m (math.exp: the C library's exp) */
static double rounding_bias(double sigma2, double q)
{
    if (!(q > 0.0)) return 0.0;
    return 0.5 * q * exp(-2.0 * PC_PI * PC_PI * sigma2 / (q * q));
}

/* PidSequencer.still: the last readings' least-squares slope within Z_DECIDE standard errors
 * of 0 (summed one after another, as the Python loop) */
static int window_still(const PcController *c)
{
    const PcLaw *L = &c->law;
    int64_t k = L->ring_n;
    double mid = 0.5 * (PC_NOISE_WINDOW - 1), first, slope = 0.0;
    int i;
    if (k < PC_NOISE_WINDOW) return 0;
    first = L->ring[py_mod(k, PC_NOISE_WINDOW)];
    for (i = 0; i < PC_NOISE_WINDOW; i++)
        slope += ((double)i - mid) * (L->ring[py_mod(k + i, PC_NOISE_WINDOW)] - first);
    slope /= PC_SLOPE_NORM;
    return fabs(slope) <= PC_Z_DECIDE * sqrt(c->rest.sigma2 / PC_SLOPE_NORM);
}

/* PidSequencer.recent_mean: the mean of the last m readings (m <= PC_NOISE_WINDOW), m */
static double window_recent_mean(const PcLaw *L, int64_t m)
{
    double total = 0.0;
    int64_t i;
    for (i = 1; i <= m; i++) total += L->ring[py_mod(L->ring_n - i, PC_NOISE_WINDOW)];
    return total / (double)m;
}

/* PidSequencer.reading_margin */
static double reading_margin(const PcRest *r)
{
    return py_max(r->band, PC_BAND_SIGMAS * sqrt(r->sigma2));
}

/* PidSequencer.pid_force: the PID acts (mode coarse) */
static double window_pid_force(PcController *c)
{
    PcSequencer *q = &c->seq;
    rest_forget_direction(&c->rest);
    q->mode = PC_MODE_COARSE;
    q->outcome = PC_OUTCOME_ACTIVE;
    q->outcome_reason = PC_REASON_NONE;
    c->law.u_last = pid_force(c, q->x_prev, q->v_hat);
    return c->law.u_last;
}

/* PidSequencer.leave_hold */
static double leave_hold(PcController *c)
{
    c->law.holding = 0;
    return window_pid_force(c);
}

/* PidSequencer.enter_hold; the PID's holding_force is none (0 N): capped, u is not held */
static double enter_hold(PcController *c, double u, int capped)
{
    PcLaw *L = &c->law;
    L->holding = 1;
    L->u_hold = capped ? 0.0 : u;
    c->seq.mode = PC_MODE_WAIT;
    L->h_x0 = c->seq.x_prev;
    L->h_sum = 0.0;
    L->h_n = -PC_NOISE_WINDOW;
    L->h_look = c->rest.dwell + 1;
    return L->u_hold;
}

/* PidSequencer.crept: the table moved under the force held */
static int window_crept(const PcController *c)
{
    const PcLaw *L = &c->law;
    int64_t n = L->h_n, w = PC_NOISE_WINDOW;
    double last, before, d;
    if (n < 2 * PC_NOISE_WINDOW) return 0;
    last = window_recent_mean(L, w);
    before = L->h_x0 + (L->h_sum - (double)w * (last - L->h_x0)) / (double)(n - w);
    d = fabs(last - before) - rounding_bias(c->rest.sigma2, c->cfg.q);
    return d > 0.0 && d * d > PC_Z_DECIDE * PC_Z_DECIDE * c->rest.sigma2 *
                                  (1.0 / (double)w + 1.0 / (double)(n - w));
}

/* PidSequencer.hold: inside the window, the force held (PidSequencer.inside), or the PID
 * again once the table is outside */
static double window_hold(PcController *c, double x_ref)
{
    PcLaw *L = &c->law;
    PcSequencer *q = &c->seq;
    double x = q->x_prev, tol = c->cfg.tolerance, e, s, bias;
    if (!pid_arrived(c) || fabs(x_ref - x) > c->cfg.w_band + reading_margin(&c->rest))
        return leave_hold(c);
    L->h_n += 1;
    if (L->h_n <= 0) {
        /* the force held settles: its readings are not yet those of the rest */
        L->h_x0 = x;
        return L->u_hold;
    }
    L->h_sum += x - L->h_x0;
    if (window_crept(c)) {
        L->h_x0 = window_recent_mean(L, PC_NOISE_WINDOW);
        L->h_sum = 0.0;
        L->h_n = PC_NOISE_WINDOW;
        L->h_look = PC_NOISE_WINDOW;
    }
    if (L->h_n < L->h_look) return L->u_hold;
    while (L->h_look <= L->h_n) L->h_look = (3 * L->h_look + 1) / 2;
    e = x_ref - (L->h_x0 + L->h_sum / (double)L->h_n);
    s = sqrt(c->rest.sigma2 / (double)L->h_n);
    bias = rounding_bias(c->rest.sigma2, c->cfg.q);
    if (fabs(e) - PC_Z_DECIDE * s - bias > c->cfg.w_band) return leave_hold(c);
    if (fabs(e) + PC_Z_DECIDE * s + bias <= tol) {
        seq_settle(c);
        return L->u_hold;
    }
    if (q->outcome == PC_OUTCOME_SETTLED && fabs(e) - PC_Z_DECIDE * s - bias > tol) {
        q->mode = PC_MODE_WAIT;
        q->outcome = PC_OUTCOME_ACTIVE;
        q->outcome_reason = PC_REASON_NONE;
    }
    return L->u_hold;
}

/* PidSequencer.coasts_into_window */
static int coasts_into_window(const PcController *c, double x_ref)
{
    double v = c->seq.v_hat, d;
    if (v == 0.0) return 0;
    d = c->cfg.m_est * v * v / (2.0 * c->cfg.f_c_est);
    return fabs(x_ref - c->seq.x_prev - copysign(d, v)) <= c->cfg.w_band;
}

/* PidSequencer.window_read: the speed, the last readings, the rest detector; whether at
 * rest by its band and dwell (the force-free readings once the reference has arrived:
 * quiet_readings) */
static int window_read(PcController *c, double x_meas, double x_ref)
{
    PcLaw *L = &c->law;
    PcSequencer *q = &c->seq;
    PcRest *r = &c->rest;
    double dx;
    int at_rest;
    L->ring[py_mod(L->ring_n, PC_NOISE_WINDOW)] = x_meas;
    L->ring_n += 1;
    if (q->first) {
        q->first = 0;
        q->v_hat = 0.0;
        rest_start_run(r, x_meas);
        q->e0 = x_ref - x_meas;
        q->x_prev = x_meas;
        return 0;
    }
    dx = x_meas - q->x_prev;
    q->v_hat = dx / c->cfg.T;
    q->x_prev = x_meas;
    at_rest = rest_read(&c->cfg, r, x_meas, L->holding != 0);
    if (pid_arrived(c)) at_rest = rest_force_free(&c->cfg, r, x_meas, dx, at_rest);
    return at_rest;
}

/* PidSequencer.window_act: the force after the reading, held inside the window, else the
 * PID's (the PID's coast_force and holding_force are none, 0 N) */
static double window_act(PcController *c, double x_ref, int at_rest)
{
    PcLaw *L = &c->law;
    PcSequencer *q = &c->seq;
    double e, side;
    if (L->holding) return window_hold(c, x_ref);
    if (L->coasting) {
        if (!pid_arrived(c)) {
            L->coasting = 0;
        } else if (at_rest && window_still(c)) {
            L->coasting = 0;
            return enter_hold(c, L->u_coast, 0);
        } else {
            return L->u_coast;
        }
    }
    if (pid_arrived(c) && !at_rest && coasts_into_window(c, x_ref)) {
        L->coasting = 1;
        L->u_coast = 0.0;
        q->mode = PC_MODE_WAIT;
        return L->u_coast;
    }
    if (pid_arrived(c) && at_rest) {
        e = x_ref - rest_x_hat(&c->rest);
        if (fabs(e) <= c->cfg.w_band && window_still(c)) return enter_hold(c, L->u_last, 1);
        side = e > 0.0 ? 1.0 : -1.0;
        if (L->side && side != L->side) L->reversals += 1;
        L->side = side;
        if (L->reversals >= c->cfg.hunt_max && fabs(e) < fabs(q->e0)) {
            L->holding = 1;
            L->u_hold = 0.0;
            seq_stop(c, PC_REASON_HUNTING);
            return L->u_hold;
        }
    }
    return window_pid_force(c);
}

/* PidSequencer.window_update: one sample of the PID with its in-position window */
static double window_update(PcController *c, double x_meas, double x_ref)
{
    PcLaw *L = &c->law;
    if (c->seq.stopped) return L->holding ? L->u_hold : 0.0;
    if (!(-PC_X_LIMIT <= x_meas && x_meas <= PC_X_LIMIT && -PC_X_LIMIT <= x_ref &&
          x_ref <= PC_X_LIMIT)) {
        L->holding = 0;
        return seq_stop(c, PC_REASON_INVALID_MEASUREMENT);
    }
    return window_act(c, x_ref, window_read(c, x_meas, x_ref));
}

/* PulseSequencer.reset */
static void seq_reset(PcController *c)
{
    PcSequencer *q = &c->seq;
    q->mode = PC_MODE_SETTLED;
    q->idle_samples = 0;
    q->idle_x = q->idle_ref = NAN;
    q->pulses = 0;
    q->first = 1;
    q->x_prev = NAN;
    q->v_hat = 0.0;
    q->pulse_left = 0;
    q->f_pulse = 0.0;
    q->n_pulse = 0;
    q->x_start = 0.0;
    q->waited = 0;
    q->last_n = 0;
    q->last_f = 0.0;
    q->last_d = 0.0;
    q->outcome = PC_OUTCOME_ACTIVE;
    q->outcome_reason = PC_REASON_NONE;
    q->stopped = 0;
    q->e0 = NAN;
    q->released = 0;
    q->stall_x = 0.0;
    q->stall_n = 0;
    q->pred = 0.0;
    rest_reset(&c->rest);
}

/* PidController._reset_law */
static void pid_reset_law(PcLaw *L)
{
    int i;
    L->k = 0;
    L->integral = 0.0;
    L->x_from = NAN;
    L->x_to = NAN;
    L->x_ref_now = 0.0;
    L->side = 0.0;
    L->reversals = 0;
    L->holding = 0;
    L->u_hold = 0.0;
    L->u_last = 0.0;
    L->coasting = 0;
    L->u_coast = 0.0;
    for (i = 0; i < PC_NOISE_WINDOW; i++) L->ring[i] = 0.0;
    L->ring_n = 0;
    L->h_x0 = 0.0;
    L->h_sum = 0.0;
    L->h_n = 0;
    L->h_look = 0;
}

/* ---- the controller ------------------------------------------------------------------- */

/* PulseControllerBase.__init__ and the laws' __init__: the derived values and the state of
 * a new controller (the settings valid). */
static void make(PcController *c, const PcSettings *s, double T)
{
    PcConfig *g = &c->cfg;
    PcLaw *L = &c->law;
    double t_p_max = t_p_max_of(s), b0, a1, a2, w, m;
    memset(c, 0, sizeof *c);
    c->magic = PC_MAGIC;
    c->size = (uint32_t)sizeof *c;
    c->settings = *s;
    g->kind = s->kind;
    g->T = T;
    g->n_max = isinf(t_p_max) ? PC_N_UNBOUNDED
                              : i_max(1, (int64_t)floor(t_p_max / T + 1e-9));
    g->guarded = s->safeguards != 0;
    g->max_pulses = s->max_pulses;
    g->mode_samples = s->f_mode > 0.0
                          ? (int64_t)ceil(PC_MODE_PERIODS / (s->f_mode * T) - 1e-9) : 0;
    g->flexible = g->mode_samples > 0;
    g->automatic = s->rest_auto != 0;
    g->rest_samples = s->rest_samples;
    g->rest_band = s->rest_band;
    g->regressor = s->regressor;
    g->update_covariance = s->update_covariance != 0;
    g->floor_mode = s->floor_mode;
    g->hunt_max = s->hunt_max;
    g->tolerance = s->tolerance;
    /* the PID decides at rest with e_band = tolerance: it hands nothing over */
    g->e_band = s->kind == PC_KIND_PID ? s->tolerance : s->e_band;
    g->f_p_max = s->f_p_max;
    g->f_c_est = s->f_c_est;
    g->m_est = s->m_est;
    g->m_d_est = s->m_d_est;
    g->k_p = s->k_p_given ? s->k_p : s->m_est * 100.0;
    g->k_d = s->k_d_given ? s->k_d : 2.0 * 0.7 * 10.0 * s->m_est;
    g->K_c = s->K_c;
    g->floor_raise = s->floor_raise;
    g->trust0 = 1.0; /* trust0 is read by none of these kinds (native_tables checks it) */
    L->f_p_floor = s->f_p_min_given ? s->f_p_min : s->f_c_est;
    c->trust.value = g->trust0;
    c->trust.ring = 0;
    c->trust.d_one = 0.0;
    /* RestDetector.__init__ */
    c->rest.sigma2 = 0.0;
    c->rest.noise_rests = 0;
    c->rest.ring_dwell = 0;
    rest_update_test(g, &c->rest);
    rest_reset(&c->rest);
    c->seq.refusal = PC_REASON_NO_MOVE_HELPS;
    seq_reset(c);
    if (s->kind == PC_KIND_PWC) {
        b0 = s->f_p_max * (s->f_p_max - s->f_c_est) / (2.0 * s->m_est * s->f_c_est);
        L->b_hat = b0;
        L->F_inv = s->F_inv0;
        g->lambda_1 = s->lambda_1;
        g->lambda_2 = s->lambda_2;
        g->b_min = py_max(b0 * 1e-3, 1e-300);
        g->b_max = b0 * 1e3;
        L->t_p_plan = 0.0;
    } else if (s->kind == PC_KIND_PAPWC) {
        a1 = 1.0 / (2.0 * s->m_est * s->f_c_est); /* Eq. (12) */
        a2 = 1.0 / (2.0 * s->m_est);
        L->a1 = a1;
        L->a2 = a2;
        g->delta_inv = s->delta_inv;
        L->p11 = g->delta_inv;
        L->p12 = 0.0;
        L->p22 = g->delta_inv;
        g->lam = s->lambda;
        g->a1_min = a1 * 1e-3;
        g->a1_max = a1 * 1e3;
        g->a2_min = a2 * 1e-3;
        g->a2_max = a2 * 1e3;
        L->f_p_plan = s->f_p_max;
        L->t_p_plan = 0.0;
    } else if (s->kind == PC_KIND_PID) {
        pid_reset_law(L);
        /* pid.pid_gains */
        w = PC_BANDWIDTH / T;
        if (s->f_mode > 0.0) w = py_min(w, 2.0 * PC_PI * s->f_mode * PC_MODE_BANDWIDTH);
        m = s->m_est;
        g->pid_k_p = !s->k_p_given ? m * w * w : s->k_p;
        g->pid_k_d = !s->k_d_given ? 2.0 * PC_ZETA * w * m : s->k_d;
        g->pid_k_i = !s->k_i_given ? PC_INTEGRAL * m * py_pow(w, 3.0) : s->k_i;
        g->a_max = s->a_max_given ? s->a_max : py_max(s->f_p_max - s->f_c_est, 0.0) /
                                                    (2.0 * s->m_est);
        if (!(g->a_max > 0.0)) g->a_max = s->f_p_max / (2.0 * s->m_est);
        g->v_max = s->v_max;
        /* pid.in_position_window */
        g->window = s->in_position_given
                        ? s->in_position != 0
                        : T <= PC_IN_POSITION_T * (1.0 + PC_IN_POSITION_T_MARGIN);
        g->w_band = s->in_position_band_given ? s->in_position_band
                                              : py_max(s->tolerance, s->x_resolution);
        g->q = s->x_resolution;
    }
}

int pc_init(PcController *c, const PcSettings *s, double T)
{
    if (pc_check(s, T, NULL, NULL, NULL) != 0) return 1;
    make(c, s, T);
    return 0;
}

/* PidController.update */
static double pid_update(PcController *c, double x_meas, double x_ref)
{
    double u;
    if (-PC_X_LIMIT <= x_meas && x_meas <= PC_X_LIMIT && -PC_X_LIMIT <= x_ref &&
        x_ref <= PC_X_LIMIT) {
        c->law.x_ref_now = x_ref;
        if (isnan(c->law.x_to)) {
            c->law.x_from = x_meas;
            c->law.x_to = x_ref;
            c->law.k = 0;
        }
    }
    u = c->cfg.window ? window_update(c, x_meas, x_ref) : seq_update(c, x_meas, x_ref);
    c->law.k += 1;
    return u;
}

double pc_update(PcController *c, double t, double x_meas, double x_ref)
{
    (void)t;
    if (c->cfg.kind == PC_KIND_PID) return pid_update(c, x_meas, x_ref);
    return seq_update(c, x_meas, x_ref);
}

void pc_reset(PcController *c)
{
    seq_reset(c);
    if (c->cfg.kind == PC_KIND_PID) pid_reset_law(&c->law);
}

void pc_outputs(const PcController *c, PcOutputs *y)
{
    double f_p = c->cfg.f_p_max, a1 = c->law.a1, a2 = c->law.a2, b;
    memset(y, 0, sizeof *y);
    if (c->cfg.kind == PC_KIND_PWC) {
        b = c->law.b_hat;
        y->b_hat = b;
        y->f_c_hat = f_p * f_p / (2.0 * c->cfg.m_est * b + f_p);
    } else if (c->cfg.kind == PC_KIND_PAPWC) {
        y->b_hat = a1 * f_p * f_p - a2 * f_p;
        y->f_c_hat = a2 / a1;
    } else {
        y->b_hat = NAN;
        y->f_c_hat = NAN;
    }
    y->f_low = law_f_low(c);
    y->pulses = (int32_t)(c->seq.pulses > INT32_MAX ? INT32_MAX : c->seq.pulses);
    y->mode = (int32_t)c->seq.mode;
    y->outcome = (int32_t)c->seq.outcome;
    y->outcome_reason = (int32_t)c->seq.outcome_reason;
}

/* ---- state check ---------------------------------------------------------------------- */

int pc_state_check(const PcController *c, char *msg, size_t len)
{
    PcController fresh;
    PcRest test;
    const PcSequencer *q = &c->seq;
    const PcRest *r = &c->rest;
    const char *what = NULL;
    if (c->magic != PC_MAGIC || c->size != (uint32_t)sizeof *c) {
        snprintf(msg, len, "not a controller state of this library (magic %#x, size %u; "
                 "expected %#x, %u)", (unsigned)c->magic, (unsigned)c->size,
                 (unsigned)PC_MAGIC, (unsigned)sizeof *c);
        return 1;
    }
    if (pc_check(&c->settings, c->cfg.T, NULL, NULL, NULL) != 0) {
        snprintf(msg, len, "its settings are not valid");
        return 1;
    }
    make(&fresh, &c->settings, c->cfg.T);
    if (memcmp(&fresh.cfg, &c->cfg, sizeof fresh.cfg) != 0) {
        snprintf(msg, len, "its derived values are not those of its settings");
        return 1;
    }
    test = *r;
    rest_update_test(&c->cfg, &test);
    if (!(test.band == r->band || (isnan(test.band) && isnan(r->band))) || test.dwell != r->dwell)
        what = "rest band and dwell differ from what its noise estimate gives";
    else if (r->n < 0 || r->look < 0 || r->ring_n < 0 || r->noise_rests < 0 ||
             r->noise_rests > PC_NOISE_MEMORY || r->turns < 0 || r->ring_dwell < 0 ||
             r->ring_dwell > PC_RING_DWELL_MAX || (r->legs != 0 && r->legs != 1) ||
             r->since_force < 0 || r->since_turn < 0 || !(r->sigma2 >= 0.0))
        what = "a count or the noise estimate of rest detection is out of its range";
    else if (q->mode < PC_MODE_COARSE || q->mode > PC_MODE_SETTLED || q->pulses < 0 ||
             q->pulse_left < 0 || q->n_pulse < 0 || q->waited < 0 || q->last_n < 0 ||
             q->stall_n < 0 || q->idle_samples < 0 || q->outcome < PC_OUTCOME_ACTIVE ||
             q->outcome > PC_OUTCOME_STOPPED || q->outcome_reason < 0 ||
             q->outcome_reason >= PC_N_REASONS || q->refusal < 0 ||
             q->refusal >= PC_N_REASONS || (q->first != 0 && q->first != 1) ||
             (q->stopped != 0 && q->stopped != 1) || (q->released != 0 && q->released != 1) ||
             q->pulse_left > c->cfg.n_max || q->n_pulse > c->cfg.n_max)
        what = "a mode, code or count of the sequencer is out of its range";
    else if ((c->trust.ring != 0 && c->trust.ring != 1) || !(c->trust.value > 0.0) ||
             c->trust.value > 1.0)
        what = "the trust region is out of its range";
    else if (c->law.k < 0 || c->law.reversals < 0 || c->law.ring_n < 0 ||
             (c->law.holding != 0 && c->law.holding != 1) ||
             (c->law.coasting != 0 && c->law.coasting != 1) || c->law.h_look < 0 ||
             (c->law.holding && !q->stopped && c->law.h_look < 1))
        what = "a count of the PID is out of its range";
    if (what != NULL) {
        snprintf(msg, len, "%s", what);
        return 1;
    }
    return 0;
}
