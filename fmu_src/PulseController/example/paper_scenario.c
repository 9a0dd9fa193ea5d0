/* paper_scenario.c: the paper's Section 4 scenario in C, with no FMI and no Python.
 *
 * PAPWC (the paper's Section 3) positions the Table 1 plant (m = 150 kg, f_c = 100 N,
 * f_s = 130 N, c = 700 N.s/m; the C plant of fmu_src/FrictionPlant/plant.c) from rest at
 * 0 to x_ref = 10 mm, sampled every T = 10 ms, ten times in a row, what it learned carried
 * from one maneuver to the next; the settings of scenarios/paper.toml's PAPWC with
 * t_p,max = 0.03 s (the laws as published: no safeguards). Each sample reads the encoder,
 * asks the controller for the force and holds that force over the next T, as a drive's
 * control loop does. One line per maneuver: its number, the final position and error (m),
 * the pulses, the outcome and its reason (controller_vars.h: PC_OUTCOME_*, PC_REASON_*).
 *
 * Build (the headers controller_vars.h and plant_vars.h come with the FMUs' sources/, or
 * from python -c "from papwc.fmubuild.native_tables import *; write_controller_header('.');
 * write_plant_header('.')"):
 *
 *     cc -std=c99 -O2 -ffp-contract=off -I. -I../../FrictionPlant -I.. paper_scenario.c \
 *        ../controller.c ../../FrictionPlant/plant.c -lm -o paper_scenario
 */
#include <stdio.h>
#include <string.h>

#include "papwc_controller.h"
#include "plant.h"

/* pc_check's report: one problem of the settings per line. */
static void print_problem(void *context, const char *message)
{
    (void)context;
    fprintf(stderr, "%s\n", message);
}

int main(void)
{
    const double T = 0.01;      /* sample period, s */
    const double x_ref = 0.01;  /* target, m */
    const int samples = 200;    /* 2 s per maneuver */
    const int maneuvers = 10;
    FpParams p;
    FpState plant;
    FpOutputs y;
    PcSettings s;
    PcController c;
    PcOutputs out;
    char msg[512];
    double u;
    int i, k;

    fp_defaults(&p); /* the plant of the paper's Table 1 */
    p.m = 150.0;
    p.f_c = 100.0;
    p.f_s = 130.0;
    p.c = 700.0;
    if (fp_check(&p, msg, sizeof msg) != 0) {
        fprintf(stderr, "plant: %s\n", msg);
        return 1;
    }

    pc_defaults(&s); /* the model layer's defaults, then the paper's PAPWC */
    s.kind = PC_KIND_PAPWC;
    s.safeguards = 0;
    s.f_p_max = 300.0;   /* N */
    s.t_p_max = 0.03;    /* s */
    s.t_p_max_given = 1; /* (false: no bound) */
    s.K_c = 0.8;
    s.tolerance = 2e-5;  /* m */
    s.m_est = 150.0;     /* kg */
    s.f_c_est = 80.0;    /* N: 0.8 f_c */
    s.delta_inv = 1e-5;  /* P(0) = delta^-1 I, Eq. (13)-(17) */
    if (pc_init(&c, &s, T) != 0) {
        pc_check(&s, T, print_problem, NULL, NULL);
        return 1;
    }

    for (i = 1; i <= maneuvers; i++) {
        memset(&plant, 0, sizeof plant);
        fp_reset(&plant, &p); /* at rest at x0 = 0 */
        pc_reset(&c);         /* a new maneuver; the estimates are kept */
        for (k = 0; k < samples; k++) {
            fp_outputs(&plant, &p, &y);
            u = pc_update(&c, k * T, y.x_meas, x_ref);
            if (fp_step(&plant, &p, u, T, msg, sizeof msg) != 0) {
                fprintf(stderr, "plant: %s\n", msg);
                return 1;
            }
        }
        fp_outputs(&plant, &p, &y);
        pc_outputs(&c, &out);
        printf("%d %.17g %.17g %d %d %d\n", i, y.x, x_ref - y.x, (int)out.pulses,
               (int)out.outcome, (int)out.outcome_reason);
    }
    return 0;
}
