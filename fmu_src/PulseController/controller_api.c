/* controller_api.c: the controller's functions for a process that loads this binary.
 *
 * papwc's master steps the C controller in process (papwc.master.native_controller), as it
 * steps the C plant: it loads the native PulseController binary and reads this one table.
 * Only the table is exported, so the pc_* functions stay hidden (no symbol of the
 * controller can be interposed by a host's) and the caller can check the layout of the
 * structs it passes: their sizes and "name:TYPE" of each field of PcSettings and PcOutputs
 * in order, separated by spaces. A drive that links the library does not need this file.
 */
#include "papwc_controller.h"

#if defined(_WIN32)
#define PC_EXPORT __declspec(dllexport)
#else
#define PC_EXPORT __attribute__((visibility("default")))
#endif

/* The version of this table; the master reads only the one it knows. */
#define CONTROLLER_API_VERSION 1

typedef struct {
    int version;               /* CONTROLLER_API_VERSION */
    size_t settings_size;      /* sizeof(PcSettings) */
    size_t outputs_size;       /* sizeof(PcOutputs) */
    size_t controller_size;    /* sizeof(PcController) */
    const char *settings;      /* the fields of PcSettings */
    const char *outputs;       /* the fields of PcOutputs */
    void (*defaults)(PcSettings *s);
    int (*check)(const PcSettings *s, double T, PcReport report, void *context,
                 PcFormat format);
    int (*init)(PcController *c, const PcSettings *s, double T);
    double (*sample)(PcController *c, double t, double x_meas, double x_ref, PcOutputs *y);
    void (*reset)(PcController *c, PcOutputs *y);
    void (*outputs_of)(const PcController *c, PcOutputs *y);
    int (*state_check)(const PcController *c, char *msg, size_t len);
} ControllerApi;

/* One sample and the outputs after it: one call per sample from the master. */
static double sample(PcController *c, double t, double x_meas, double x_ref, PcOutputs *y)
{
    double u = pc_update(c, t, x_meas, x_ref);
    pc_outputs(c, y);
    return u;
}

/* A new maneuver and the outputs after it. */
static void reset(PcController *c, PcOutputs *y)
{
    pc_reset(c);
    pc_outputs(c, y);
}

#define FIELD_OF_SETTING(name, vr, type, start, lo, hi, lo_open, hi_open, inf_ok, unit, words) \
    #name ":" #type " "
#define FIELD_OF_SWITCH(name, vr, setting, optional, start, unit) #name ":PC_BOOLEAN "
#define FIELD_OF_OUTPUT(name, vr, type, start) #name ":" #type " "

static const ControllerApi controller_api = {
    CONTROLLER_API_VERSION, sizeof(PcSettings), sizeof(PcOutputs), sizeof(PcController),
    "kind:PC_INTEGER " PC_SETTINGS(FIELD_OF_SETTING) PC_SWITCHES(FIELD_OF_SWITCH),
    PC_OUTPUT_FIELDS(FIELD_OF_OUTPUT),
    pc_defaults, pc_check, pc_init, sample, reset, pc_outputs, pc_state_check,
};

PC_EXPORT const ControllerApi *papwc_controller_api(void);

const ControllerApi *papwc_controller_api(void) { return &controller_api; }
