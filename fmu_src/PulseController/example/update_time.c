/* update_time.c: how long one pc_update takes at most, in a C host, over closed loops.
 *
 * Reads runs from stdin, one block each:
 *
 *     run LABEL T SAMPLES ITERATIONS X_REF
 *     p NAME VALUE      (a parameter of the C plant, FpParams; repeated)
 *     s NAME VALUE      (a setting of the controller, PcSettings: kind as its code,
 *                        switches 0 or 1; repeated)
 *     end
 *
 * closes the loop of each (the C plant of plant.c, the controller of controller.c, the
 * plant restarted and the controller reset at each iteration, as papwc's master does) and
 * times every pc_update with this thread's CPU clock (time the process spends descheduled
 * does not count). A run is closed REPEATS times (the first argument, default 3: the same
 * samples each time, the run being deterministic); its longest update is the smallest of
 * the REPEATS longest (a cache or page fault of one repetition aside). Prints one line per
 * run: its label, that longest update (ns), the sum over the first repetition's updates
 * (ns) and their number; then one line "clock" with the smallest step the clock showed
 * (ns). papwc bench runs it on scenarios/realism.toml's runs
 * (papwc.bench.native_controller).
 *
 *     cc -std=c99 -O2 -ffp-contract=off -I. -I../../FrictionPlant -I.. update_time.c \
 *        ../controller.c ../../FrictionPlant/plant.c -lm -o update_time
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "papwc_controller.h"
#include "plant.h"

static long long now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

/* Set plant parameter or setting name to value: 0, or 1 for a name there is not. */
static int set_plant(FpParams *p, const char *name, double value)
{
#define X(name_, vr, type, start, lo, hi, lo_open, hi_open) \
    if (strcmp(name, #name_) == 0) { p->name_ = (type == FP_REAL) ? value : (int)value; return 0; }
    FP_PARAMETERS(X)
#undef X
    return 1;
}

static int set_setting(PcSettings *s, const char *name, double value)
{
    if (strcmp(name, "kind") == 0) {
        s->kind = (int32_t)value;
        return 0;
    }
#define X(name_, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    if (strcmp(name, #name_) == 0) { s->name_ = (type == PC_REAL) ? value : (int)value; return 0; }
    PC_SETTINGS(X)
#undef X
#define X(name_, vr, setting, optional, start, unit) \
    if (strcmp(name, #name_) == 0) { s->name_ = value != 0.0; return 0; }
    PC_SWITCHES(X)
#undef X
    return 1;
}

static void report(void *context, const char *message)
{
    fprintf(stderr, "%s: %s\n", (const char *)context, message);
}

int main(int argc, char **argv)
{
    char line[512], label[128], kind[8], name[64], msg[512];
    double T = 0.01, x_ref = 0.0, value, u;
    int samples = 0, iterations = 0, i, k, r, repeats = argc > 1 ? atoi(argv[1]) : 3;
    long long start, took, worst, longest, sum, count, tick = -1, a, b;
    FpParams p;
    FpState plant;
    FpOutputs y;
    PcSettings s;
    PcController c;
    for (i = 0; i < 1000; i++) { /* the clock's resolution */
        a = now_ns();
        do b = now_ns(); while (b == a);
        if (tick < 0 || b - a < tick) tick = b - a;
    }
    while (fgets(line, sizeof line, stdin) != NULL) {
        if (sscanf(line, "run %127s %lf %d %d %lf", label, &T, &samples, &iterations,
                   &x_ref) == 5) {
            fp_defaults(&p);
            pc_defaults(&s);
            continue;
        }
        if (sscanf(line, "%7s %63s %lf", kind, name, &value) == 3) {
            if ((kind[0] == 'p' && set_plant(&p, name, value)) ||
                (kind[0] == 's' && set_setting(&s, name, value))) {
                fprintf(stderr, "%s: no %s %s\n", label, kind[0] == 'p' ? "parameter" : "setting",
                        name);
                return 2;
            }
            continue;
        }
        if (strncmp(line, "end", 3) != 0) continue;
        if (fp_check(&p, msg, sizeof msg) != 0) {
            fprintf(stderr, "%s: plant: %s\n", label, msg);
            return 2;
        }
        if (pc_init(&c, &s, T) != 0) {
            pc_check(&s, T, report, label, NULL);
            return 2;
        }
        longest = -1;
        sum = count = 0;
        for (r = 0; r < (repeats > 0 ? repeats : 1); r++) {
            pc_init(&c, &s, T); /* the same run again */
            worst = 0;
            for (i = 0; i < iterations; i++) {
                memset(&plant, 0, sizeof plant);
                fp_reset(&plant, &p);
                pc_reset(&c);
                for (k = 0; k < samples; k++) {
                    fp_outputs(&plant, &p, &y);
                    start = now_ns();
                    u = pc_update(&c, k * T, y.x_meas, x_ref);
                    took = now_ns() - start;
                    worst = took > worst ? took : worst;
                    if (r == 0) {
                        sum += took;
                        count += 1;
                    }
                    if (fp_step(&plant, &p, u, T, msg, sizeof msg) != 0) {
                        fprintf(stderr, "%s: plant: %s\n", label, msg);
                        return 2;
                    }
                }
            }
            longest = longest < 0 || worst < longest ? worst : longest;
        }
        printf("%s %lld %lld %lld\n", label, longest, sum, count);
    }
    printf("clock %lld\n", tick);
    return 0;
}
