/* plant.h: the friction plant of papwc in C (Eq. (1) and its deviations).
 *
 * The same physics as the Python model layer (papwc.model.dynamics.Plant,
 * papwc.model.stickslip, papwc.model.rodas, papwc.model.effects), written
 * operation for operation in the same order: with every deviation at its
 * default a step is bit for bit that of Plant; with deviations it is the same
 * RODAS4 integration, event location and counter-based random draws.
 * tests/unit/test_native_physics.py checks the two against each other.
 *
 * C99, re-entrant: no globals, no allocation. Units are SI (kg, N, N.s/m, m,
 * m/s, s). Compile without -ffast-math and with -ffp-contract=off.
 */
#ifndef FP_PLANT_H
#define FP_PLANT_H

#include <stddef.h>
#include <stdint.h>

#include "plant_vars.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The plant's full state (papwc.model.dynamics.STATE_FIELDS): plain data, no
 * pointers, so copying it copies the state whole, random-draw counters included. */
typedef struct {
    double x;              /* table position, m */
    double v;              /* table velocity, m/s (exactly 0.0 while stuck) */
    double z;              /* LuGre bristle deflection, m */
    double x_d;            /* motor position of the flexible drive, m */
    double v_d;            /* motor velocity, m/s */
    double f_a;            /* force applied by the lagging actuator, N */
    double f_s_now;        /* breakaway force in effect (random stiction), N */
    uint64_t stick_draws;  /* breakaway forces drawn so far */
    uint64_t noise_draws;  /* communication points so far when an encoder is noisy */
    double noise;          /* encoder noise at the last communication point, m */
    double h_next;         /* the integrator's step size proposal, s (0: none yet) */
} FpState;

/* The fields of FpState: X(name, type) with type FP_REAL (double) or FP_COUNT (uint64_t). */
#define FP_COUNT 3
#define FP_STATE_FIELDS(X) \
    X(x, FP_REAL) X(v, FP_REAL) X(z, FP_REAL) X(x_d, FP_REAL) X(v_d, FP_REAL) \
    X(f_a, FP_REAL) X(f_s_now, FP_REAL) X(stick_draws, FP_COUNT) X(noise_draws, FP_COUNT) \
    X(noise, FP_REAL) X(h_next, FP_REAL)

/* The model layer's default of every parameter (PLANT_DEFAULTS). */
void fp_defaults(FpParams *p);

/* The rules between parameters (papwc.model.plant.PLANT_CONSTRAINTS): 0 if all hold,
 * else nonzero and msg names the first rule violated with the values, in the model
 * layer's words (plant_problems' first message; the longest is under 300 bytes, so a
 * msg of 512 bytes holds each whole). The range of each parameter on its own is not
 * checked here (FP_PARAMETERS gives it); the thresholds, the deviations that make the
 * plant integrated and the maxima of the rules come from plant_vars.h. */
int fp_check(const FpParams *p, char *msg, size_t len);

/* The state at the start (Plant.reset): at x0 with v0, spring relaxed, no force
 * applied, the first breakaway force and encoder noise drawn. */
void fp_reset(FpState *s, const FpParams *p);

/* Advance over h (s) with the force u (N) held (Plant.step). 0: done; nonzero: refused
 * (u not finite, h not finite and > 0, or what Plant.step refuses), the state is left
 * as it was and msg says why. */
int fp_step(FpState *s, const FpParams *p, double u, double h, char *msg, size_t len);

/* Whether a state (e.g. one deserialized) can be restored (Plant.set_state): 0 if every
 * field is finite; else nonzero and msg names the field and its value. */
int fp_state_check(const FpState *s, char *msg, size_t len);

/* The outputs at the last communication point: x, v, x_meas (Plant.x_meas), stuck,
 * x_d (Plant.x_d_now) and x_d_meas (Plant.x_d_meas, the motor encoder). */
void fp_outputs(const FpState *s, const FpParams *p, FpOutputs *y);

#ifdef __cplusplus
}
#endif

#endif
