/* plant.c: the friction plant of papwc in C (see plant.h).
 *
 * Each function below is the one of the Python model layer named in its comment,
 * written with the same operations in the same order, so that the same doubles come
 * out: Python floats are IEEE doubles and math.exp, log, expm1, log1p, sin, cos, pow
 * and sqrt call the C library's functions. Where Python raises (a logarithm of a
 * number <= 0, a sine of an infinity, a division by zero, a singular matrix, too many
 * steps or events), the step is refused here as it is there, and the state is kept.
 */
#include "plant.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define FP_PI 3.141592653589793
/* Most state components: x, v, z, x_d, v_d, f_a. */
#define FP_N_MAX 6
/* exp(-p) is exactly 0.0 in double precision beyond this exponent (effects/stribeck.py). */
#define FP_P_ZERO 746.0
/* Bisection of an event stops at this width, a fraction of the step (2**-45). */
#define FP_EVENT_WIDTH (1.0 / 35184372088832.0)
/* Below this value of z = c*t/m, phi2 is summed as a series (stickslip.py). */
#define FP_PHI2_SERIES_BELOW 0.05

/* ---- messages ---------------------------------------------------------------------------- */

/* Whether the decimal n*10^e reads back as x. */
static int reads_back(unsigned long long n, int e, double x)
{
    char buf[48];
    double back;
    snprintf(buf, sizeof buf, "%llue%d", n, e);
    return sscanf(buf, "%lf", &back) == 1 && back == x;
}

/* The shortest decimal n*10^e (n with p <= 17 digits) that reads back as x > 0, and of
 * those the nearest to x, as Python's repr finds it. */
static void shortest(double x, unsigned long long *n_out, int *e_out)
{
    char buf[48];
    const char *c;
    unsigned long long n = 0;
    int p, e = 0;
    for (p = 1; p <= 17; p++) {
        snprintf(buf, sizeof buf, "%.*e", p - 1, x);
        n = 0;
        for (c = buf; *c && *c != 'e'; c++)
            if (*c >= '0' && *c <= '9')
                n = 10 * n + (unsigned long long)(*c - '0');
        sscanf(c + 1, "%d", &e);
        e -= p - 1;
        /* The nearest p digits; else the p digits on the other side of x may read back. */
        if (reads_back(n, e, x))
            break;
        if (n > 1 && reads_back(n - 1, e, x)) {
            n -= 1;
            break;
        }
        if (reads_back(n + 1, e, x)) {
            n += 1;
            break;
        }
    }
    while (n >= 10 && n % 10 == 0) {
        n /= 10;
        e += 1;
    }
    *n_out = n;
    *e_out = e;
}

/* x as Python's repr writes it (shortest digits that read back exactly). */
static void py_repr(double x, char *out, size_t len)
{
    char digits[24], buf[16];
    const char *c;
    unsigned long long n;
    int e, nd, i, pos = 0;
    if (len == 0)
        return;
    if (x != x) {
        snprintf(out, len, "nan");
        return;
    }
    if (isinf(x)) {
        snprintf(out, len, x > 0 ? "inf" : "-inf");
        return;
    }
    if (x == 0.0) {
        snprintf(out, len, signbit(x) ? "-0.0" : "0.0");
        return;
    }
    shortest(fabs(x), &n, &e);
    nd = snprintf(digits, sizeof digits, "%llu", n);
    e += nd - 1; /* the exponent of the first digit */
#define PUT(ch) do { if ((size_t)pos + 1 < len) out[pos++] = (ch); } while (0)
    if (x < 0)
        PUT('-');
    if (e < -4 || e >= 16) {
        PUT(digits[0]);
        if (nd > 1) {
            PUT('.');
            for (i = 1; i < nd; i++)
                PUT(digits[i]);
        }
        snprintf(buf, sizeof buf, "e%c%02d", e < 0 ? '-' : '+', e < 0 ? -e : e);
        for (c = buf; *c; c++)
            PUT(*c);
    } else if (e < 0) {
        PUT('0');
        PUT('.');
        for (i = 0; i < -e - 1; i++)
            PUT('0');
        for (i = 0; i < nd; i++)
            PUT(digits[i]);
    } else {
        for (i = 0; i <= e; i++)
            PUT(i < nd ? digits[i] : '0');
        PUT('.');
        if (nd > e + 1)
            for (i = e + 1; i < nd; i++)
                PUT(digits[i]);
        else
            PUT('0');
    }
#undef PUT
    out[pos] = '\0';
}

/* x as Python's format(x, f".{precision}g") writes it (1 <= precision <= 17): the
 * digits rounded to nearest (ties to even on the exact value, as printf's %e does), then
 * fixed notation for a decimal exponent in [-4, precision), else d.ddde+XX with at least
 * two exponent digits; trailing zeros and a trailing point dropped. Written here rather
 * than left to printf's %g, whose exponent has three digits in some C libraries. */
static void py_g(double x, int precision, char *out, size_t len)
{
    char buf[48], digits[24];
    const char *c;
    int nd = 0, e = 0, i, pos = 0;
    if (len == 0)
        return;
    if (x != x) {
        snprintf(out, len, "nan");
        return;
    }
    if (isinf(x)) {
        snprintf(out, len, x > 0 ? "inf" : "-inf");
        return;
    }
    snprintf(buf, sizeof buf, "%.*e", precision - 1, fabs(x));
    for (c = buf; *c && *c != 'e'; c++)
        if (*c >= '0' && *c <= '9' && nd < (int)sizeof digits - 1)
            digits[nd++] = *c;
    if (*c == 'e')
        sscanf(c + 1, "%d", &e);
    while (nd > 1 && digits[nd - 1] == '0')
        nd--;
#define PUT(ch) do { if ((size_t)pos + 1 < len) out[pos++] = (ch); } while (0)
    if (signbit(x))
        PUT('-');
    if (x == 0.0) {
        PUT('0');
    } else if (e < -4 || e >= precision) {
        PUT(digits[0]);
        if (nd > 1) {
            PUT('.');
            for (i = 1; i < nd; i++)
                PUT(digits[i]);
        }
        snprintf(buf, sizeof buf, "e%c%02d", e < 0 ? '-' : '+', e < 0 ? -e : e);
        for (c = buf; *c; c++)
            PUT(*c);
    } else if (e < 0) {
        PUT('0');
        PUT('.');
        for (i = 0; i < -e - 1; i++)
            PUT('0');
        for (i = 0; i < nd; i++)
            PUT(digits[i]);
    } else {
        for (i = 0; i <= e; i++)
            PUT(i < nd ? digits[i] : '0');
        if (nd > e + 1) {
            PUT('.');
            for (i = e + 1; i < nd; i++)
                PUT(digits[i]);
        }
    }
#undef PUT
    out[pos] = '\0';
}

static void say(char *msg, size_t len, const char *text)
{
    if (msg != NULL && len > 0)
        snprintf(msg, len, "%s", text);
}

/* ---- random draws (effects/draws.py) ----------------------------------------------------- */

static uint64_t mix(uint64_t z)
{
    z = z + UINT64_C(0x9E3779B97F4A7C15);
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    return z ^ (z >> 31);
}

/* draws.uniform: draw k of a stream under seed, in the open interval (0, 1). */
static double uniform(int32_t seed, unsigned stream, uint64_t k)
{
    uint64_t z = mix(mix(((uint64_t)(int64_t)seed << 8) | (uint64_t)(stream & 0xFFu)) ^ k);
    return ((double)(z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/* statistics.NormalDist().inv_cdf(p), 0 < p < 1 (Wichura, AS241), as Python computes it. */
static double inv_cdf(double p)
{
    double q = p - 0.5, r, num, den, x;
    if (fabs(q) <= 0.425) {
        r = 0.180625 - q * q;
        num = (((((((2.5090809287301226727e+3 * r +
                     3.3430575583588128105e+4) * r +
                     6.7265770927008700853e+4) * r +
                     4.5921953931549871457e+4) * r +
                     1.3731693765509461125e+4) * r +
                     1.9715909503065514427e+3) * r +
                     1.3314166789178437745e+2) * r +
                     3.3871328727963666080e+0) * q;
        den = (((((((5.2264952788528545610e+3 * r +
                     2.8729085735721942674e+4) * r +
                     3.9307895800092710610e+4) * r +
                     2.1213794301586595867e+4) * r +
                     5.3941960214247511077e+3) * r +
                     6.8718700749205790830e+2) * r +
                     4.2313330701600911252e+1) * r +
                     1.0);
        x = num / den;
        return 0.0 + (x * 1.0);
    }
    r = q <= 0.0 ? p : 1.0 - p;
    r = sqrt(-log(r));
    if (r <= 5.0) {
        r = r - 1.6;
        num = (((((((7.74545014278341407640e-4 * r +
                     2.27238449892691845833e-2) * r +
                     2.41780725177450611770e-1) * r +
                     1.27045825245236838258e+0) * r +
                     3.64784832476320460504e+0) * r +
                     5.76949722146069140550e+0) * r +
                     4.63033784615654529590e+0) * r +
                     1.42343711074968357734e+0);
        den = (((((((1.05075007164441684324e-9 * r +
                     5.47593808499534494600e-4) * r +
                     1.51986665636164571966e-2) * r +
                     1.48103976427480074590e-1) * r +
                     6.89767334985100004550e-1) * r +
                     1.67638483018380384940e+0) * r +
                     2.05319162663775882187e+0) * r +
                     1.0);
    } else {
        r = r - 5.0;
        num = (((((((2.01033439929228813265e-7 * r +
                     2.71155556874348757815e-5) * r +
                     1.24266094738807843860e-3) * r +
                     2.65321895265761230930e-2) * r +
                     2.96560571828504891230e-1) * r +
                     1.78482653991729133580e+0) * r +
                     5.46378491116411436990e+0) * r +
                     6.65790464350110377720e+0);
        den = (((((((2.04426310338993978564e-15 * r +
                     1.42151175831644588870e-7) * r +
                     1.84631831751005468180e-5) * r +
                     7.86869131145613259100e-4) * r +
                     1.48753612908506148525e-2) * r +
                     1.36929880922735805310e-1) * r +
                     5.99832206555887937690e-1) * r +
                     1.0);
    }
    x = num / den;
    if (q < 0.0)
        x = -x;
    return 0.0 + (x * 1.0);
}

/* stiction.RandomStiction.draw: breakaway force number k, N. */
static double stiction_draw(const FpParams *p, uint64_t k)
{
    return p->f_s * (1.0 + p->f_s_spread * (2.0 * uniform(p->seed, FP_STREAM_STICTION, k) - 1.0));
}

/* encoder.EncoderNoise.draw: noise at communication point number k, m. */
static double noise_draw(const FpParams *p, uint64_t k)
{
    return p->noise_std * inv_cdf(uniform(p->seed, FP_STREAM_NOISE, k));
}

/* The motor encoder's EncoderNoise.draw (its own stream): noise at point number k, m. */
static double motor_noise_draw(const FpParams *p, uint64_t k)
{
    return p->x_d_noise_std * inv_cdf(uniform(p->seed, FP_STREAM_MOTOR_NOISE, k));
}

/* ---- Eq. (1) in closed form (stickslip.py) ----------------------------------------------- */

static double phi1(double z)
{
    if (z == 0.0)
        return 1.0;
    return -expm1(-z) / z;
}

static double phi2(double z)
{
    if (z < FP_PHI2_SERIES_BELOW)
        return 0.5 - z * (1.0 / 6.0 - z * (1.0 / 24.0 - z * (1.0 / 120.0
               - z * (1.0 / 720.0 - z * (1.0 / 5040.0 - z * (1.0 / 40320.0))))));
    return (z + expm1(-z)) / (z * z);
}

static double psi(double y)
{
    if (y == 0.0)
        return 1.0;
    return log1p(y) / y;
}

/* stickslip.step: advance (x, v) exactly over h with the force u held. */
static void exact_step(double x, double v, double u, double h, double m, double f_c,
                       double f_s, double c, double *x_out, double *v_out)
{
    double s, force, y, t_star, z, p1, x_end, v_end;
    if (v == 0.0) {
        if (-f_s <= u && u <= f_s) {
            *x_out = x;
            *v_out = 0.0;
            return;
        }
        s = u > 0.0 ? 1.0 : -1.0;
        force = u - s * f_c;
    } else {
        s = v > 0.0 ? 1.0 : -1.0;
        force = u - s * f_c;
        if (s * force < 0.0) {
            y = -c * v / force;
            t_star = -(m * v / force) * psi(y);
            if (t_star < h) {
                z = c * t_star / m;
                x += v * t_star * phi1(z) + (force / m) * t_star * t_star * phi2(z);
                h -= t_star;
                if (-f_s <= u && u <= f_s) {
                    *x_out = x;
                    *v_out = 0.0;
                    return;
                }
                s = -s;
                force = u - s * f_c;
                v = 0.0;
            }
        }
    }
    z = c * h / m;
    p1 = phi1(z);
    x_end = x + v * h * p1 + (force / m) * h * h * phi2(z);
    v_end = v * exp(-z) + (force / m) * h * p1;
    if (s * v_end < 0.0)
        v_end = 0.0;
    *x_out = x_end;
    *v_out = v_end;
}

/* stickslip.stop_time: time a sliding mass takes to reach v = 0 under u. */
static double stop_time(double v, double u, double m, double f_c, double c)
{
    double s, force, y;
    if (v == 0.0)
        return 0.0;
    s = v > 0.0 ? 1.0 : -1.0;
    force = u - s * f_c;
    if (!(s * force < 0.0))
        return INFINITY;
    y = -c * v / force;
    return -(m * v / force) * psi(y);
}

/* stickslip.quantize: the encoder's rounding to its count. */
static double quantize(double x, double resolution)
{
    double q, n;
    if (resolution <= 0.0)
        return x;
    q = x / resolution;
    n = floor(q);
    if (n == 0.0)
        n = 0.0; /* math.floor gives the integer 0 for -0.0: no sign */
    return (q - n >= 0.5 ? n + 1.0 : n) * resolution;
}

/* ---- the plant with deviations (dynamics.py) --------------------------------------------- */

typedef struct {
    const FpParams *p;
    FpState *w;        /* the state being advanced (f_s_now and the draws live here) */
    int stribeck, lugre, ripple, stiction, lag, flexible, encoder, noisy, exact, is_eq1;
    double w_zero;     /* Stribeck.shape: speeds above which S is 0.0 exactly */
    double ripple_k;   /* Ripple.k = 2*pi/ripple_period, rad/m */
    double rate_gain;  /* ActuatorLag.rate_gain = 1/tau_u, 1/s */
    int n, iz, ixd, ivd, ifa;
    double atol[FP_N_MAX], rtol[FP_N_MAX];
    int fail;          /* the step is refused */
    const char *kind;  /* the exception Python raised there (NULL: a reason it returned) */
    int bare;          /* Plant._integrate caught the exception: its text alone is the reason */
    char why[200];
} Model;

/* Refuse the step: Python raised the exception `kind` with `text` here (kind NULL: Python
 * returned `text` as the reason). The first failure is kept. */
static void fail(Model *M, const char *kind, const char *text)
{
    if (!M->fail) {
        M->fail = 1;
        M->kind = kind;
        snprintf(M->why, sizeof M->why, "%s", text);
    }
}

#define ZERO_DIVISION "ZeroDivisionError"
#define ARITHMETIC "ArithmeticError"
#define VALUE "ValueError"

/* Plant.__init__ and Plant._layout: which effects are present, the state vector. */
static void model_init(Model *M, const FpParams *p, FpState *w)
{
    double force;
    int i = 0;
    memset(M, 0, sizeof *M);
    M->p = p;
    M->w = w;
    M->stribeck = p->v_s > 0.0;
    M->lugre = p->sigma_0 > 0.0;
    M->ripple = p->ripple > 0.0;
    M->stiction = p->f_s_spread > 0.0;
    M->lag = p->tau_u > 0.0;
    M->flexible = p->m_d > 0.0;
    M->encoder = p->noise_std > 0.0;
    M->noisy = M->encoder || p->x_d_noise_std > 0.0;
    M->exact = !(M->stribeck || M->lugre || M->ripple || M->lag || M->flexible);
    M->is_eq1 = M->exact && !M->stiction && !M->noisy;
    if (M->stribeck)
        M->w_zero = p->v_s * pow(FP_P_ZERO, 1.0 / p->delta_s);
    if (M->ripple)
        M->ripple_k = 2.0 * FP_PI / p->ripple_period;
    if (M->lag)
        M->rate_gain = 1.0 / p->tau_u;
    /* force = max(f_s, f_c, 1.0) as Python's max picks it */
    force = p->f_s;
    if (p->f_c > force)
        force = p->f_c;
    if (1.0 > force)
        force = 1.0;
    M->iz = M->ixd = M->ivd = M->ifa = -1;
    M->atol[i] = FP_ATOL_X * 1.0;
    M->rtol[i++] = FP_RTOL_X;
    M->atol[i] = FP_ATOL_V * 1.0;
    M->rtol[i++] = FP_RTOL_V;
    if (M->lugre) {
        M->iz = i;
        M->atol[i] = FP_ATOL_Z * (force / p->sigma_0);
        M->rtol[i++] = FP_RTOL_Z;
    }
    if (M->flexible) {
        M->ixd = i;
        M->atol[i] = FP_ATOL_X_D * 1.0;
        M->rtol[i++] = FP_RTOL_X_D;
        M->ivd = i;
        M->atol[i] = FP_ATOL_V_D * 1.0;
        M->rtol[i++] = FP_RTOL_V_D;
    }
    if (M->lag) {
        M->ifa = i;
        M->atol[i] = FP_ATOL_F_A * force;
        M->rtol[i++] = FP_RTOL_F_A;
    }
    M->n = i;
}

static void pack(const Model *M, double *y)
{
    const FpState *w = M->w;
    y[0] = w->x;
    y[1] = w->v;
    if (M->iz >= 0)
        y[M->iz] = w->z;
    if (M->ixd >= 0) {
        y[M->ixd] = w->x_d;
        y[M->ivd] = w->v_d;
    }
    if (M->ifa >= 0)
        y[M->ifa] = w->f_a;
}

static void unpack(Model *M, const double *y)
{
    FpState *w = M->w;
    w->x = y[0];
    w->v = y[1];
    if (M->iz >= 0)
        w->z = y[M->iz];
    if (M->ixd >= 0) {
        w->x_d = y[M->ixd];
        w->v_d = y[M->ivd];
    }
    if (M->ifa >= 0)
        w->f_a = y[M->ifa];
}

/* Plant._redraw: a new breakaway force (random stiction). */
static void redraw(Model *M)
{
    if (M->stiction) {
        M->w->f_s_now = stiction_draw(M->p, M->w->stick_draws);
        M->w->stick_draws += 1;
    }
}

/* Stribeck.shape: S(w) and dS/dw at the speed w >= 0. */
static void stribeck_shape(const Model *M, double w, double *s, double *slope)
{
    const FpParams *p = M->p;
    double q;
    if (w >= M->w_zero) {
        *s = 0.0;
        *slope = 0.0;
        return;
    }
    if (w == 0.0) {
        *s = 1.0;
        *slope = p->delta_s == 1.0 ? -1.0 / p->v_s : 0.0;
        return;
    }
    q = pow(w / p->v_s, p->delta_s);
    *s = exp(-q);
    *slope = -p->delta_s * q / w * *s;
}

/* Ripple.factor: r(x) and dr/dx. math.sin and math.cos refuse an infinity. */
static void ripple_factor(Model *M, double x, double *r, double *r_x)
{
    const FpParams *p = M->p;
    double arg = M->ripple_k * x + p->ripple_phase;
    if (isinf(arg))
        fail(M, VALUE, "math domain error");
    *r = 1.0 + p->ripple * sin(arg);
    *r_x = p->ripple * M->ripple_k * cos(arg);
}

/* Plant._level: steady sliding friction g at (x, v) and its derivatives by x and v. */
static void level(Model *M, double x, double v, double s, double *g, double *g_x, double *g_v)
{
    const FpParams *p = M->p;
    double base, base_v, shape, slope, rise, sgn, r, r_x;
    if (M->stribeck) {
        stribeck_shape(M, fabs(v), &shape, &slope);
        rise = M->w->f_s_now - p->f_c;
        base = shape == 1.0 ? M->w->f_s_now : p->f_c + rise * shape;
        sgn = v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : s);
        base_v = rise * slope * sgn;
    } else {
        base = p->f_c;
        base_v = 0.0;
    }
    if (M->ripple) {
        ripple_factor(M, x, &r, &r_x);
        *g = r * base;
        *g_x = r_x * base;
        *g_v = r * base_v;
        return;
    }
    *g = base;
    *g_x = 0.0;
    *g_v = base_v;
}

/* Plant._breakaway: the force the stuck table holds before it breaks away. */
static double breakaway(Model *M, double x)
{
    double r, r_x;
    if (M->ripple) {
        ripple_factor(M, x, &r, &r_x);
        return r * M->w->f_s_now;
    }
    return M->w->f_s_now;
}

/* FlexibleMode.coupling: force of the coupling on the table. */
static double coupling(const FpParams *p, double x, double v, double x_d, double v_d)
{
    return p->k_t * (x_d - x) + p->c_t * (v_d - v);
}

/* Plant._drive: force on the table from the drive. */
static double drive_force(const Model *M, const double *y, double u)
{
    if (M->flexible)
        return coupling(M->p, y[0], y[1], y[M->ixd], y[M->ivd]);
    if (M->lag)
        return y[M->ifa];
    return u;
}

/* Plant._rates: dy/dt; s the direction of sliding, 0 while stuck. */
static void rates(Model *M, const double *y, double u, double s, double *out)
{
    const FpParams *p = M->p;
    double x = y[0], v = y[1], f_a, drive, v_d, sgn, g, g_x, g_v, z, z_rate;
    int i;
    for (i = 0; i < M->n; i++)
        out[i] = 0.0;
    f_a = M->lag ? y[M->ifa] : u;
    if (M->lag)
        out[M->ifa] = (u - f_a) * M->rate_gain;
    if (M->flexible) {
        v_d = y[M->ivd];
        drive = coupling(p, x, v, y[M->ixd], v_d);
        out[M->ixd] = v_d;
        out[M->ivd] = (f_a - drive) / p->m_d;
    } else {
        drive = f_a;
    }
    if (M->lugre) {
        sgn = v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
        level(M, x, v, sgn, &g, &g_x, &g_v);
        if (g == 0.0)
            fail(M, ZERO_DIVISION, "float division by zero");
        z = y[M->iz];
        z_rate = v - p->sigma_0 * fabs(v) * z / g;
        out[0] = v;
        out[1] = (drive - (p->sigma_0 * z + p->sigma_1 * z_rate) - p->c * v) / p->m;
        out[M->iz] = z_rate;
    } else if (s != 0.0) {
        level(M, x, v, s, &g, &g_x, &g_v);
        out[0] = v;
        out[1] = (drive - s * g - p->c * v) / p->m;
    }
}

/* Plant._jacobian: d(dy/dt)/dy. */
static void jacobian(Model *M, const double *y, double u, double s, double jac[][FP_N_MAX])
{
    const FpParams *p = M->p;
    int n = M->n, i, j, k, np = 0;
    int pj[4];
    double pd[4];
    double x = y[0], v = y[1], inv_m = 1.0 / p->m, inv_md, *row;
    double sgn, g, g_x, g_v, z, w, inv_g, dz_x, dz_v, dz_z, s0, s1;
    (void)u;
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            jac[i][j] = 0.0;
    if (M->lag)
        jac[M->ifa][M->ifa] = -M->rate_gain;
    if (M->flexible) {
        pj[0] = M->ixd; pd[0] = p->k_t;
        pj[1] = 0;      pd[1] = -p->k_t;
        pj[2] = M->ivd; pd[2] = p->c_t;
        pj[3] = 1;      pd[3] = -p->c_t;
        np = 4;
        inv_md = 1.0 / p->m_d;
        jac[M->ixd][M->ivd] = 1.0;
        row = jac[M->ivd];
        for (k = 0; k < np; k++)
            row[pj[k]] -= pd[k] * inv_md;
        if (M->lag)
            row[M->ifa] += inv_md;
    } else if (M->lag) {
        pj[0] = M->ifa;
        pd[0] = 1.0;
        np = 1;
    }
    if (!M->lugre && s == 0.0)
        return;
    jac[0][1] = 1.0;
    row = jac[1];
    for (k = 0; k < np; k++)
        row[pj[k]] += pd[k] * inv_m;
    if (M->lugre) {
        sgn = v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
        level(M, x, v, sgn, &g, &g_x, &g_v);
        z = y[M->iz];
        /* LuGre.partials */
        s0 = p->sigma_0;
        w = fabs(v);
        if (g == 0.0)
            fail(M, ZERO_DIVISION, "float division by zero");
        inv_g = 1.0 / g;
        dz_x = s0 * w * z * g_x * inv_g * inv_g;
        dz_v = 1.0 - s0 * z * (sgn - w * g_v * inv_g) * inv_g;
        dz_z = -s0 * w * inv_g;
        s1 = p->sigma_1;
        row[0] -= s1 * dz_x * inv_m;
        row[1] -= (s1 * dz_v + p->c) * inv_m;
        row[M->iz] -= (p->sigma_0 + s1 * dz_z) * inv_m;
        jac[M->iz][0] = dz_x;
        jac[M->iz][1] = dz_v;
        jac[M->iz][M->iz] = dz_z;
    } else {
        level(M, x, v, s, &g, &g_x, &g_v);
        row[0] -= s * g_x * inv_m;
        row[1] -= (s * g_v + p->c) * inv_m;
    }
}

/* ---- RODAS4 (rodas.py) ------------------------------------------------------------------- */

#define GAMMA 0.25
#define A21 1.544
#define A31 0.9466785280815826
#define A32 0.2557011698983284
#define A41 3.314825187068521
#define A42 2.896124015972201
#define A43 0.9986419139977817
#define A51 1.221224509226641
#define A52 6.019134481288629
#define A53 12.53708332932087
#define A54 (-0.6878860361058950)
#define C21 (-5.6688)
#define C31 (-2.430093356833875)
#define C32 (-0.2063599157091915)
#define C41 (-0.1073529058151375)
#define C42 (-9.594562251023355)
#define C43 (-20.47028614809616)
#define C51 7.496443313967647
#define C52 (-10.24680431464352)
#define C53 (-33.99990352819905)
#define C54 11.70890893206160
#define C61 8.083246795921522
#define C62 (-7.981132988064893)
#define C63 (-31.52159432874371)
#define C64 16.31930543123136
#define C65 (-6.058818238834054)
#define D21 10.12623508344586
#define D22 (-7.487995877610167)
#define D23 (-34.80091861555747)
#define D24 (-7.992771707568823)
#define D25 1.025137723295662
#define D31 (-0.6762803392801253)
#define D32 6.087714651680015
#define D33 16.43084320892478
#define D34 24.76722511418386
#define D35 (-6.594389125716872)

/* rodas.inverse: Gauss-Jordan with partial pivoting (closed form for 2 x 2). 0: singular. */
static int inverse(int n, double a[][FP_N_MAX], double inv[][FP_N_MAX])
{
    double rows[FP_N_MAX][2 * FP_N_MAX], tmp[2 * FP_N_MAX], best, inv_pivot, factor, det;
    int i, j, k, piv, width = 2 * n;
    if (n == 2) {
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        if (det == 0.0)
            return 0;
        inv[0][0] = a[1][1] / det;
        inv[0][1] = -a[0][1] / det;
        inv[1][0] = -a[1][0] / det;
        inv[1][1] = a[0][0] / det;
        return 1;
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++) {
            rows[i][j] = a[i][j];
            rows[i][n + j] = i == j ? 1.0 : 0.0;
        }
    for (k = 0; k < n; k++) {
        piv = k;
        best = fabs(rows[k][k]);
        for (i = k + 1; i < n; i++)
            if (fabs(rows[i][k]) > best) {
                piv = i;
                best = fabs(rows[i][k]);
            }
        if (best == 0.0)
            return 0;
        if (piv != k) {
            memcpy(tmp, rows[k], sizeof tmp);
            memcpy(rows[k], rows[piv], sizeof tmp);
            memcpy(rows[piv], tmp, sizeof tmp);
        }
        inv_pivot = 1.0 / rows[k][k];
        for (j = k; j < width; j++)
            rows[k][j] *= inv_pivot;
        for (i = 0; i < n; i++)
            if (i != k) {
                factor = rows[i][k];
                if (factor != 0.0)
                    for (j = k; j < width; j++)
                        rows[i][j] -= factor * rows[k][j];
            }
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            inv[i][j] = rows[i][n + j];
    return 1;
}

/* rodas.matvec: r[0]*b[0] + r[1]*b[1] + ... per row, summed left to right. */
static void matvec(int n, double m[][FP_N_MAX], const double *b, double *out)
{
    int i, j;
    double acc;
    for (i = 0; i < n; i++) {
        acc = m[i][0] * b[0];
        for (j = 1; j < n; j++)
            acc = acc + m[i][j] * b[j];
        out[i] = acc;
    }
}

/* rodas.rodas4_step: one step of size h; y_new, err and the stages k1..k5. 0: singular. */
static int rodas4_step(Model *M, const double *y, const double *f0, double jac[][FP_N_MAX],
                       double h, double u, double s, double *y_new, double *err,
                       double stages[5][FP_N_MAX])
{
    int n = M->n, i, j;
    double a[FP_N_MAX][FP_N_MAX], inv[FP_N_MAX][FP_N_MAX];
    double t[FP_N_MAX], f[FP_N_MAX], y5[FP_N_MAX], y6[FP_N_MAX];
    double *k1 = stages[0], *k2 = stages[1], *k3 = stages[2], *k4 = stages[3], *k5 = stages[4];
    double diag, inv_h, c21;
    if (GAMMA * h == 0.0 || h == 0.0) {
        fail(M, ZERO_DIVISION, "float division by zero");
        return 0;
    }
    diag = 1.0 / (GAMMA * h);
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            a[i][j] = -jac[i][j];
    for (i = 0; i < n; i++)
        a[i][i] += diag;
    if (!inverse(n, a, inv)) {
        fail(M, ZERO_DIVISION, "singular iteration matrix");
        return 0;
    }
    inv_h = 1.0 / h;
    matvec(n, inv, f0, k1);
    for (i = 0; i < n; i++)
        t[i] = y[i] + A21 * k1[i];
    rates(M, t, u, s, f);
    c21 = C21 * inv_h;
    for (i = 0; i < n; i++)
        t[i] = f[i] + c21 * k1[i];
    matvec(n, inv, t, k2);
    for (i = 0; i < n; i++)
        t[i] = y[i] + A31 * k1[i] + A32 * k2[i];
    rates(M, t, u, s, f);
    for (i = 0; i < n; i++)
        t[i] = f[i] + inv_h * (C31 * k1[i] + C32 * k2[i]);
    matvec(n, inv, t, k3);
    for (i = 0; i < n; i++)
        t[i] = y[i] + A41 * k1[i] + A42 * k2[i] + A43 * k3[i];
    rates(M, t, u, s, f);
    for (i = 0; i < n; i++)
        t[i] = f[i] + inv_h * (C41 * k1[i] + C42 * k2[i] + C43 * k3[i]);
    matvec(n, inv, t, k4);
    for (i = 0; i < n; i++)
        y5[i] = y[i] + A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i];
    rates(M, y5, u, s, f);
    for (i = 0; i < n; i++)
        t[i] = f[i] + inv_h * (C51 * k1[i] + C52 * k2[i] + C53 * k3[i] + C54 * k4[i]);
    matvec(n, inv, t, k5);
    for (i = 0; i < n; i++)
        y6[i] = y5[i] + k5[i];
    rates(M, y6, u, s, f);
    for (i = 0; i < n; i++)
        t[i] = f[i] + inv_h * (C61 * k1[i] + C62 * k2[i] + C63 * k3[i] + C64 * k4[i]
                               + C65 * k5[i]);
    matvec(n, inv, t, err);
    for (i = 0; i < n; i++)
        y_new[i] = y6[i] + err[i];
    return 1;
}

/* rodas.dense and rodas.dense_value: component i of the continuous extension at theta. */
typedef struct {
    double y0, y1, c3, c4;
} Dense;

static Dense dense(double y0, double y1, double stages[5][FP_N_MAX], int i)
{
    Dense d;
    double k1 = stages[0][i], k2 = stages[1][i], k3 = stages[2][i], k4 = stages[3][i],
           k5 = stages[4][i];
    d.y0 = y0;
    d.y1 = y1;
    d.c3 = D21 * k1 + D22 * k2 + D23 * k3 + D24 * k4 + D25 * k5;
    d.c4 = D31 * k1 + D32 * k2 + D33 * k3 + D34 * k4 + D35 * k5;
    return d;
}

static double dense_value(const Dense *d, double theta)
{
    double s1 = 1.0 - theta;
    return d->y0 * s1 + theta * (d->y1 + s1 * (d->c3 + theta * d->c4));
}

/* ---- integration with stick-slip events (dynamics.py) ------------------------------------ */

/* Plant._error: the largest error relative to its tolerance (<= 1: accepted). */
static double error_norm(const Model *M, const double *y, const double *y1, const double *err)
{
    double worst = 0.0, q, a, b;
    int i;
    for (i = 0; i < M->n; i++) {
        a = fabs(y[i]);
        b = fabs(y1[i]);
        q = fabs(err[i]) / (M->atol[i] + M->rtol[i] * (b > a ? b : a));
        if (!(q <= worst))
            worst = q;
    }
    return worst;
}

/* Plant._mode: direction of sliding at a state (0: stuck). */
static double mode(Model *M, const double *y, double u)
{
    double v = y[1], drive;
    if (v != 0.0)
        return v > 0.0 ? 1.0 : -1.0;
    drive = drive_force(M, y, u);
    if (fabs(drive) > breakaway(M, y[0]))
        return drive > 0.0 ? 1.0 : -1.0;
    return 0.0;
}

/* Plant._switch: apply a stick-slip event at y (in place); the new direction. */
static double switch_mode(Model *M, double *y, double u, double s)
{
    double drive = drive_force(M, y, u);
    if (s != 0.0) {
        y[1] = 0.0;
        if (fabs(drive) <= breakaway(M, y[0])) {
            redraw(M);
            if (fabs(drive) <= breakaway(M, y[0]))
                return 0.0;
        }
    }
    return drive > 0.0 ? 1.0 : -1.0;
}

/* Plant._accepted_step: one RODAS4 step that meets the tolerance, shrinking *h until it
 * does. 0: done; else M->fail (too many steps, a step size at the floor, a singular
 * matrix or what Python raises). */
static int accepted_step(Model *M, const double *y, double u, double s, double *h,
                         long *steps, double h_floor, double *y1,
                         double stages[5][FP_N_MAX], double *q_out, int *shrunk)
{
    double f0[FP_N_MAX], jac[FP_N_MAX][FP_N_MAX], err[FP_N_MAX], q, grow;
    char text[120], hr[40];
    rates(M, y, u, s, f0);
    jacobian(M, y, u, s, jac);
    if (M->fail)
        return 1;
    *shrunk = 0;
    for (;;) {
        *steps += 1;
        if (*steps > FP_MAX_STEPS) {
            snprintf(text, sizeof text, "the integrator needed more than %d steps in one "
                     "communication step", FP_MAX_STEPS);
            fail(M, ARITHMETIC, text);
            return 1;
        }
        if (!rodas4_step(M, y, f0, jac, *h, u, s, y1, err, stages) || M->fail)
            return 1;
        if (s == 0.0 && !M->lugre) {
            y1[0] = y[0];
            y1[1] = 0.0;
            err[0] = 0.0;
            err[1] = 0.0;
        }
        q = error_norm(M, y, y1, err);
        if (q <= 1.0) {
            *q_out = q;
            return 0;
        }
        if (isfinite(q)) {
            grow = 0.9 * pow(q, -0.25);
            *h *= grow > 0.1 ? grow : 0.1;
        } else {
            *h *= 0.1;
        }
        *shrunk = 1;
        if (*h <= h_floor) {
            py_repr(*h, hr, sizeof hr);
            snprintf(text, sizeof text, "the integrator's step size fell below %s s", hr);
            fail(M, ARITHMETIC, text);
            return 1;
        }
    }
}

static double grow_factor(double q)
{
    double g;
    if (!(q > 0.0))
        return 5.0;
    g = 0.9 * pow(q, -0.25);
    return g < 5.0 ? g : 5.0;
}

/* Plant._event: fraction of the step where the first stick-slip event happens; -1: none. */
static double event(Model *M, const double *y, const double *y1, double stages[5][FP_N_MAX],
                    double u, double s)
{
    static const double samples[4] = {0.25, 0.5, 0.75, 1.0};
    Dense v_of, of[3];
    int moving[3], nm = 0, i, k, found = 0;
    double limit = 0.0, state[FP_N_MAX], lo = 0.0, hi = 1.0, mid, theta;
    int crossed;
    if (s != 0.0) {
        v_of = dense(y[1], y1[1], stages, 1);
    } else {
        if (!M->lag && !M->flexible)
            return -1.0;
        limit = breakaway(M, y[0]);
        if (M->ixd >= 0)
            moving[nm++] = M->ixd;
        if (M->ivd >= 0)
            moving[nm++] = M->ivd;
        if (M->ifa >= 0)
            moving[nm++] = M->ifa;
        for (k = 0; k < nm; k++)
            of[k] = dense(y[moving[k]], y1[moving[k]], stages, moving[k]);
        for (i = 0; i < M->n; i++)
            state[i] = y[i];
    }
#define CROSSED(th, out) do { \
        double th_ = (th); \
        if (s != 0.0) { \
            (out) = s * (th_ == 1.0 ? y1[1] : dense_value(&v_of, th_)) <= 0.0; \
        } else if (th_ == 1.0) { \
            (out) = fabs(drive_force(M, y1, u)) > limit; \
        } else { \
            for (k = 0; k < nm; k++) \
                state[moving[k]] = dense_value(&of[k], th_); \
            (out) = fabs(drive_force(M, state, u)) > limit; \
        } \
    } while (0)
    for (i = 0; i < 4; i++) {
        theta = samples[i];
        CROSSED(theta, crossed);
        if (crossed) {
            hi = theta;
            found = 1;
            break;
        }
        lo = theta;
    }
    if (!found)
        return -1.0;
    while (hi - lo > FP_EVENT_WIDTH) {
        mid = 0.5 * (lo + hi);
        CROSSED(mid, crossed);
        if (crossed)
            hi = mid;
        else
            lo = mid;
    }
#undef CROSSED
    return hi;
}

/* Plant._stuck_lag: a stuck table under the lagging force over `remaining`, in closed form.
 * y advances to the breakaway instant (returns 1, *t_break its time) or to the end (0). */
static int stuck_lag(Model *M, double *y, double u, double remaining, double *t_break)
{
    int ifa = M->ifa;
    double tau = M->p->tau_u, f0 = y[ifa], limit = breakaway(M, y[0]), bound, arg, t, f_a;
    if (fabs(u) > limit) {
        bound = u > 0.0 ? limit : -limit;
        arg = (f0 - u) / (bound - u);
        if (arg <= 0.0) {
            fail(M, VALUE, "math domain error");
            return 0;
        }
        t = tau * log(arg);
        t = t > 0.0 ? t : 0.0;
        if (t < remaining) {
            f_a = f0 - (u - f0) * expm1(-t / tau);
            if (!(fabs(f_a) > limit))
                f_a = nextafter(bound, u);
            y[ifa] = f_a;
            *t_break = t;
            return 1;
        }
    }
    y[ifa] = f0 - (u - f0) * expm1(-remaining / tau);
    return 0;
}

/* Plant._advance_to: integrate over h_end without events; 0: done, else M->fail. */
static int advance_to(Model *M, double *y, double u, double s, double h_end, long *taken)
{
    double t = 0.0, h = h_end, remaining, y1[FP_N_MAX], stages[5][FP_N_MAX], q;
    long steps = 0;
    int last, shrunk, i;
    while (t < h_end) {
        remaining = h_end - t;
        last = h >= remaining;
        if (last)
            h = remaining;
        if (accepted_step(M, y, u, s, &h, &steps, 0.0, y1, stages, &q, &shrunk))
            return 1;
        last = last && !shrunk;
        for (i = 0; i < M->n; i++)
            y[i] = y1[i];
        t = last ? h_end : t + h;
        h *= grow_factor(q);
    }
    *taken = steps;
    return 0;
}

/* Plant._integrate: one communication step with the stick-slip events; 0 or M->fail. */
static int integrate(Model *M, double u, double h_total)
{
    double y[FP_N_MAX], y1[FP_N_MAX], stages[5][FP_N_MAX];
    double s, t = 0.0, h, remaining, q, grow, theta, t_break, h_event;
    int lugre = M->lugre, frozen = !M->lag && !M->flexible, last, shrunk, i;
    long steps = 0, events = 0, taken = 0;
    char text[120];
    pack(M, y);
    s = lugre ? 0.0 : mode(M, y, u);
    h = M->w->h_next > 0.0 ? M->w->h_next : h_total / 8.0;
    while (t < h_total && !M->fail) {
        if (s == 0.0 && !lugre) {
            if (frozen)
                break;
            if (!M->flexible) {
                if (!stuck_lag(M, y, u, h_total - t, &t_break))
                    break;
                t += t_break;
                events += 1;
                s = switch_mode(M, y, u, s);
                continue;
            }
        }
        remaining = h_total - t;
        last = h >= remaining;
        if (last)
            h = remaining;
        if (accepted_step(M, y, u, s, &h, &steps, 1e-15 * h_total, y1, stages, &q, &shrunk)) {
            /* Plant._integrate catches ArithmeticError here and returns its text. */
            M->bare = M->kind != NULL && strcmp(M->kind, VALUE) != 0;
            return 1;
        }
        last = last && !shrunk;
        grow = grow_factor(q);
        theta = lugre ? -1.0 : event(M, y, y1, stages, u, s);
        if (theta < 0.0) {
            for (i = 0; i < M->n; i++)
                y[i] = y1[i];
            t = last ? h_total : t + h;
            h *= grow;
            continue;
        }
        events += 1;
        if (events > FP_MAX_EVENTS) {
            snprintf(text, sizeof text, "more than %d stick-slip events in one communication "
                     "step", FP_MAX_EVENTS);
            fail(M, NULL, text);
            return 1;
        }
        h_event = theta * h;
        if (advance_to(M, y, u, s, h_event, &taken))
            return 1;
        steps += taken;
        t += h_event;
        s = switch_mode(M, y, u, s);
    }
    if (M->fail)
        return 1;
    unpack(M, y);
    M->w->h_next = h;
    return 0;
}

/* Plant._advance_stiction: Eq. (1) in closed form, the breakaway force redrawn where the
 * mass sticks. */
static void advance_stiction(Model *M, double u, double h)
{
    const FpParams *p = M->p;
    FpState *w = M->w;
    double v = w->v, x1, v1, t_stick;
    exact_step(w->x, v, u, h, p->m, p->f_c, w->f_s_now, p->c, &x1, &v1);
    if (v != 0.0 && v1 == 0.0) {
        redraw(M);
        if (!(-w->f_s_now <= u && u <= w->f_s_now)) {
            t_stick = stop_time(v, u, p->m, p->f_c, p->c);
            if (t_stick < h)
                exact_step(x1, 0.0, u, h - t_stick, p->m, p->f_c, w->f_s_now, p->c, &x1, &v1);
        }
    }
    w->x = x1;
    w->v = v1;
}

static int state_finite(const FpState *w)
{
    return isfinite(w->x) && isfinite(w->v) && isfinite(w->z) && isfinite(w->x_d)
           && isfinite(w->v_d) && isfinite(w->f_a) && isfinite(w->f_s_now)
           && isfinite(w->noise) && isfinite(w->h_next);
}

/* ---- the API ----------------------------------------------------------------------------- */

void fp_defaults(FpParams *p)
{
#define FP_DEFAULT(name, vr, type, start, lo, hi, lo_open, hi_open) p->name = start;
    FP_PARAMETERS(FP_DEFAULT)
#undef FP_DEFAULT
}

void fp_reset(FpState *s, const FpParams *p)
{
    memset(s, 0, sizeof *s);
    s->x = p->x0;
    s->v = p->v0;
    s->z = 0.0;
    s->x_d = p->x0;
    s->v_d = p->v0;
    s->f_a = 0.0;
    s->f_s_now = p->f_s;
    s->stick_draws = 0;
    s->noise_draws = 0;
    s->noise = 0.0;
    s->h_next = 0.0;
    if (p->f_s_spread > 0.0) {
        s->f_s_now = stiction_draw(p, 0);
        s->stick_draws = 1;
    }
    if (p->noise_std > 0.0 || p->x_d_noise_std > 0.0) {
        if (p->noise_std > 0.0)
            s->noise = noise_draw(p, 0);
        s->noise_draws = 1;
    }
}

int fp_step(FpState *s, const FpParams *p, double u, double h, char *msg, size_t len)
{
    Model M;
    FpState w;
    double x1, v1;
    char a[40], text[300];
    if (!isfinite(u)) {
        py_repr(u, a, sizeof a);
        snprintf(text, sizeof text, "input u = %s N is not finite", a);
        say(msg, len, text);
        return 1;
    }
    if (!(0.0 < h && h < INFINITY)) {
        py_repr(h, a, sizeof a);
        snprintf(text, sizeof text, "step size %s s must be finite and > 0", a);
        say(msg, len, text);
        return 1;
    }
    w = *s;
    model_init(&M, p, &w);
    if (M.is_eq1) {
        /* Plant._step_exact */
        exact_step(w.x, w.v, u, h, p->m, p->f_c, p->f_s, p->c, &x1, &v1);
        if (!(isfinite(x1) && isfinite(v1))) {
            say(msg, len, "the result would not be finite");
            return 1;
        }
        s->x = x1;
        s->v = v1;
        return 0;
    }
    /* Plant._step_checked */
    if (M.exact)
        advance_stiction(&M, u, h);
    else
        integrate(&M, u, h);
    if (!M.fail && !state_finite(&w))
        fail(&M, NULL, "the result would not be finite");
    if (M.fail) {
        /* Plant._step_checked: an exception that reached it is "the integration failed". */
        if (M.kind != NULL && !M.bare) {
            snprintf(text, sizeof text, "the integration failed: %s: %s", M.kind, M.why);
            say(msg, len, text);
        } else {
            say(msg, len, M.why);
        }
        return 1;
    }
    if (M.noisy) {
        if (M.encoder)
            w.noise = noise_draw(p, w.noise_draws);
        w.noise_draws += 1;
    }
    *s = w;
    return 0;
}

int fp_state_check(const FpState *s, char *msg, size_t len)
{
    char a[40], text[120];
#define FP_STATE_FINITE(name, type) \
    if ((type) == FP_REAL && !isfinite((double)s->name)) { \
        py_repr((double)s->name, a, sizeof a); \
        snprintf(text, sizeof text, "plant state field %s = %s is not finite", #name, a); \
        say(msg, len, text); \
        return 1; \
    }
    FP_STATE_FIELDS(FP_STATE_FINITE)
#undef FP_STATE_FINITE
    return 0;
}

void fp_outputs(const FpState *s, const FpParams *p, FpOutputs *y)
{
    y->x = s->x;
    y->v = s->v;
    if (p->noise_std > 0.0)
        y->x_meas = quantize(s->x + s->noise, p->x_resolution);
    else
        y->x_meas = quantize(s->x, p->x_resolution);
    y->stuck = s->v == 0.0;
    /* Plant.x_d_now and Plant.x_d_meas: the motor side (x on a rigid drive). */
    y->x_d = p->m_d > 0.0 ? s->x_d : s->x;
    if (p->x_d_noise_std > 0.0)
        y->x_d_meas = quantize(y->x_d + motor_noise_draw(p, s->noise_draws - 1), p->x_d_resolution);
    else
        y->x_d_meas = quantize(y->x_d, p->x_d_resolution);
}

/* The first deviation of papwc.model.plant.INTEGRATED that is on (> 0): its name, and
 * its value in *value; NULL if none (plant._integrated). */
static const char *integrated(const FpParams *p, double *value)
{
#define FP_FIRST_ON(name) \
    if (p->name > 0.0) { \
        *value = p->name; \
        return #name; \
    }
    FP_INTEGRATED(FP_FIRST_ON)
#undef FP_FIRST_ON
    *value = 0.0;
    return NULL;
}

/* The message of an off-or-at-least rule (plant._off_or_at_least): name = value is
 * neither 0 nor >= low_text; which (if not NULL) is the integrated deviation that makes
 * the rule apply. Returns 1 (refused). */
static int off_refused(const char *name, double value, const char *low_text,
                       const char *unit, const char *which, double which_value, char *msg,
                       size_t len)
{
    char a[40], b[40], when[120], text[512];
    py_repr(value, a, sizeof a);
    when[0] = '\0';
    if (which != NULL) {
        py_repr(which_value, b, sizeof b);
        snprintf(when, sizeof when, " when the plant is integrated (%s = %s > 0)", which, b);
    }
    snprintf(text, sizeof text, "%s = %s%s: must be 0 (none) or >= %s%s%s (a smaller one has "
             "no effect at the plant's steps, and makes them overflow or take unbounded time)",
             name, a, unit, low_text, unit, when);
    say(msg, len, text);
    return 1;
}

/* The rules between parameters (papwc.model.plant.PLANT_CONSTRAINTS), in their order;
 * the message is the model layer's, word for word (values as repr writes them, the
 * model layer's {x:.6g} by py_g). The thresholds, the deviations that make the plant
 * integrated and the maxima come from plant_vars.h, generated from the model layer. */
int fp_check(const FpParams *p, char *msg, size_t len)
{
    char a[40], b[40], c[40], d[40], g[40], text[512];
    const char *which;
    double lowest, f, which_value;
    if (p->f_s < p->f_c) {
        py_repr(p->f_s, a, sizeof a);
        py_repr(p->f_c, b, sizeof b);
        snprintf(text, sizeof text, "f_s = %s N: must be >= f_c = %s N", a, b);
        say(msg, len, text);
        return 1;
    }
    /* _off_or_at_least(name, low) for OFF_OR_AT_LEAST */
#define FP_OFF(name, low, low_text, unit) \
    if (p->name != 0.0 && fabs(p->name) < (low)) \
        return off_refused(#name, p->name, low_text, unit, NULL, 0.0, msg, len);
    FP_OFF_OR_AT_LEAST(FP_OFF)
#undef FP_OFF
    /* _off_or_at_least(name, low, integrated=True) for INTEGRATED_OFF_OR_AT_LEAST */
    which = integrated(p, &which_value);
#define FP_OFF_INTEGRATED(name, low, low_text, unit) \
    if (p->name != 0.0 && fabs(p->name) < (low) && which != NULL) \
        return off_refused(#name, p->name, low_text, unit, which, which_value, msg, len);
    FP_INTEGRATED_OFF_OR_AT_LEAST(FP_OFF_INTEGRATED)
#undef FP_OFF_INTEGRATED
    /* _acceleration_bounded */
    if (which != NULL && p->f_s / p->m > FP_ACCELERATION_MAX) {
        py_repr(p->m, a, sizeof a);
        py_g(p->f_s / p->m, 6, g, sizeof g);
        py_repr(p->f_s, b, sizeof b);
        py_repr(which_value, c, sizeof c);
        snprintf(text, sizeof text, "m = %s kg: the breakaway force gives the mass f_s/m = %s "
                 "m/s^2 (f_s = %s N); must be <= %s m/s^2 when the plant is integrated "
                 "(%s = %s > 0)", a, g, b, FP_ACCELERATION_MAX_TEXT, which, c);
        say(msg, len, text);
        return 1;
    }
    /* _damping_bounded */
    if (which != NULL && p->c / p->m > FP_DAMPING_RATE_MAX) {
        py_repr(p->c, a, sizeof a);
        py_g(p->c / p->m, 6, g, sizeof g);
        py_repr(p->m, b, sizeof b);
        py_repr(which_value, c, sizeof c);
        snprintf(text, sizeof text, "c = %s N.s/m: the damping rate c/m = %s 1/s (m = %s kg) "
                 "must be <= %s 1/s when the plant is integrated (%s = %s > 0)", a, g, b,
                 FP_DAMPING_RATE_MAX_TEXT, which, c);
        say(msg, len, text);
        return 1;
    }
    if (p->m_d > 0.0 && p->c_t * (1.0 / p->m + 1.0 / p->m_d) > FP_DAMPING_RATE_MAX) {
        f = p->c_t * (1.0 / p->m + 1.0 / p->m_d);
        py_repr(p->c_t, a, sizeof a);
        py_g(f, 6, g, sizeof g);
        py_repr(p->m, b, sizeof b);
        py_repr(p->m_d, c, sizeof c);
        snprintf(text, sizeof text, "c_t = %s N.s/m: the coupling's damping rate c_t*(1/m + "
                 "1/m_d) = %s 1/s (m = %s kg, m_d = %s kg) must be <= %s 1/s", a, g, b, c,
                 FP_DAMPING_RATE_MAX_TEXT);
        say(msg, len, text);
        return 1;
    }
    lowest = p->f_s * (1.0 - p->f_s_spread);
    if (p->f_s_spread > 0.0 && lowest < p->f_c) {
        py_repr(p->f_s_spread, a, sizeof a);
        py_repr(lowest, b, sizeof b);
        py_repr(p->f_c, c, sizeof c);
        snprintf(text, sizeof text, "f_s_spread = %s: the lowest breakaway force "
                 "f_s*(1 - f_s_spread) = %s N must be >= f_c = %s N", a, b, c);
        say(msg, len, text);
        return 1;
    }
    if (p->sigma_0 > 0.0 && !(p->f_c > 0.0)) {
        py_repr(p->sigma_0, a, sizeof a);
        py_repr(p->f_c, b, sizeof b);
        snprintf(text, sizeof text, "sigma_0 = %s N/m: the LuGre model needs f_c > 0 (its "
                 "bristle equation divides by the sliding friction); f_c = %s N", a, b);
        say(msg, len, text);
        return 1;
    }
    if (p->f_s_spread > 0.0 && p->sigma_0 > 0.0) {
        py_repr(p->f_s_spread, a, sizeof a);
        py_repr(p->sigma_0, b, sizeof b);
        snprintf(text, sizeof text, "f_s_spread = %s: random stiction redraws the breakaway "
                 "force each time the mass sticks, and with LuGre (sigma_0 = %s N/m > 0) it "
                 "never sticks; set f_s_spread or sigma_0 to 0", a, b);
        say(msg, len, text);
        return 1;
    }
    if (p->m_d > 0.0 && !(p->k_t > 0.0)) {
        py_repr(p->k_t, a, sizeof a);
        py_repr(p->m_d, b, sizeof b);
        snprintf(text, sizeof text, "k_t = %s N/m: a flexible drive (m_d = %s kg > 0) needs "
                 "a coupling stiffness k_t > 0", a, b);
        say(msg, len, text);
        return 1;
    }
    if (p->sigma_0 > 0.0) {
        f = sqrt(p->sigma_0 / p->m) / (2.0 * FP_PI);
        if (f > FP_MODE_FREQUENCY_MAX) {
            py_repr(p->sigma_0, a, sizeof a);
            py_repr(p->m, b, sizeof b);
            py_g(f, 6, g, sizeof g);
            snprintf(text, sizeof text, "sigma_0 = %s N/m: the pre-sliding mode "
                     "sqrt(sigma_0/m)/(2*pi) = %s Hz (m = %s kg) must be <= %s Hz",
                     a, g, b, FP_MODE_FREQUENCY_MAX_TEXT);
            say(msg, len, text);
            return 1;
        }
    }
    if (p->m_d > 0.0 && p->k_t > 0.0) {
        f = sqrt(p->k_t * (1.0 / p->m + 1.0 / p->m_d)) / (2.0 * FP_PI);
        if (f > FP_MODE_FREQUENCY_MAX) {
            py_repr(p->k_t, a, sizeof a);
            py_repr(p->m, c, sizeof c);
            py_repr(p->m_d, d, sizeof d);
            py_g(f, 6, g, sizeof g);
            snprintf(text, sizeof text, "k_t = %s N/m: the flexible mode sqrt(k_t*(1/m + "
                     "1/m_d))/(2*pi) = %s Hz (m = %s kg, m_d = %s kg) must be <= %s Hz; a "
                     "stiffer drive is rigid: m_d = 0", a, g, c, d, FP_MODE_FREQUENCY_MAX_TEXT);
            say(msg, len, text);
            return 1;
        }
    }
    return 0;
}
