/*
 * A counterbalance valve as an FMI 2.0 co-simulation FMU: generic C for every fitted valve.
 *
 * Written by cbv-surrogate (surrogate/export/fmu.py); the valve itself is data, the tables in
 * resources/tables.bin, read at instantiation. Nothing here depends on the model, its maps or
 * its effects: the package tabulated them with its own solver.
 *
 * Inputs q [m3/s], p_B [Pa], p_P [Pa], T [K]; outputs p_L [Pa], dp [Pa], u [m]; SI units.
 *
 * The valve is quasi-static: friction holds the piston anywhere inside a band whose edges,
 * u_open (piston opening) and u_close (closing), are tabulated over (q, p_B, p_P, T) with the
 * pressure drop at each. The play (the internal state u, r):
 *
 *   lo, hi = smaller and larger edge (dp_lo, dp_hi their pressure drops)
 *   u < lo:  u = lo, dp = dp_lo, r = dp_lo / dp_table(q, u, p_B, T)   (pushed open)
 *   u > hi:  u = hi, dp = dp_hi, r = dp_hi / dp_table(q, u, p_B, T)   (pushed closed)
 *   else:    u held, dp = r * dp_table(q, u, p_B, T)
 *
 * The piston starts closed (u = 0, r = 1). Outputs answer the inputs set now with the piston
 * where the last step left it; fmi2DoStep(t, h) commits the play for the inputs set at t (one
 * step, one update: the step size does not matter). Tables are interpolated by cubic Hermite
 * with central-difference slopes (Catmull-Rom on even nodes) in ln(value), along ln q and ln u
 * and the other axes as they are,
 * each input held to its axis' range: the same arithmetic as surrogate.export.tables.
 *
 * An input beyond the tables' range is held at its edge. The Integer output "outside" says
 * which inputs were held at the last step (bit 1 q above the highest tabulated flow or below
 * zero, 2 p_B, 4 p_P, 8 T: any bit set means the valve is read beyond what was tabulated), and
 * the logger warns once each time an input leaves the range. A flow between zero and the
 * lowest tabulated one is the nearly closed valve at its cracking point, held and not flagged.
 */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the FMI 2.0 types this file needs (the standard's headers are not required) ---- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum {
    fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated
} fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define EXPORT __attribute__((visibility("default")))

/* ---- tables ---- */
enum { AXIS_Q, AXIS_U, AXIS_PB, AXIS_PP, AXIS_T, AXES };
enum { U_OPEN, U_CLOSE, DP_OPEN, DP_CLOSE, DP_HELD, TABLES };
#define MAX_DIMENSIONS 5

typedef struct {
    int dimensions;
    int axis[MAX_DIMENSIONS];     /* AXIS_* of each dimension */
    int count[MAX_DIMENSIONS];    /* nodes along it */
    double *nodes[MAX_DIMENSIONS];/* ln(node) for q and u, the node otherwise */
    double *values;               /* ln(value), the last dimension varying fastest */
} Table;

typedef struct {
    Table table[TABLES];
    double inputs[4];             /* q, p_B, p_P, T */
    double u, ratio;              /* the play's state */
    int outside;                  /* OUTSIDE_* of the inputs held at the last step */
    int loaded;
    char instance[128];           /* the instance's name, copied: the importer's may not last */
    const fmi2CallbackFunctions *callbacks;
} Valve;

enum { VR_Q, VR_PB, VR_PP, VR_T, VR_PL, VR_DP, VR_U, VARIABLES };
#define VR_OUTSIDE 7              /* the Integer output */
static const char *INPUT_NAMES[4] = {"q", "p_B", "p_P", "T"};
static const int INPUT_AXES[4] = {AXIS_Q, AXIS_PB, AXIS_PP, AXIS_T};
/* display unit of each input: factor and offset from SI */
static const char *INPUT_UNITS[4] = {"L/min", "bar", "bar", "degC"};
static const double INPUT_FACTORS[4] = {60000.0, 1e-5, 1e-5, 1.0};
static const double INPUT_OFFSETS[4] = {0.0, 0.0, 0.0, -273.15};

static void say(Valve *valve, fmi2Status status, const char *format, ...) {
    char message[512];
    va_list arguments;
    va_start(arguments, format);
    vsnprintf(message, sizeof message, format, arguments);
    va_end(arguments);
    if (valve && valve->callbacks && valve->callbacks->logger)
        valve->callbacks->logger(valve->callbacks->componentEnvironment, valve->instance, status,
                                 status == fmi2OK ? "logStatusOK"
                                 : (status == fmi2Warning ? "logStatusWarning" : "logStatusError"),
                                 "%s",
                                 message);
}

static int is_log_axis(int axis) { return axis == AXIS_Q || axis == AXIS_U; }

static int read_ints(FILE *file, int *into, size_t count) {
    return fread(into, sizeof(int), count, file) == count;
}

static void free_tables(Valve *valve) {
    for (int t = 0; t < TABLES; t++) {
        Table *table = &valve->table[t];
        for (int d = 0; d < MAX_DIMENSIONS; d++) { free(table->nodes[d]); table->nodes[d] = NULL; }
        free(table->values);
        table->values = NULL;
    }
}

/* tables.bin: "CBVTAB01", int32 tables; per table: int32 dimensions, int32 (axis, count) per
 * dimension, float64 nodes per dimension, float32 values (little-endian, C order) */
static int load_tables(Valve *valve, const char *path) {
    FILE *file = fopen(path, "rb");
    char magic[8];
    int tables = 0;
    if (!file) { say(valve, fmi2Error, "cannot open %s", path); return 0; }
    if (fread(magic, 1, 8, file) != 8 || memcmp(magic, "CBVTAB01", 8) != 0
        || !read_ints(file, &tables, 1) || tables != TABLES) {
        say(valve, fmi2Error, "%s: not a cbv-surrogate tables file (version 1)", path);
        fclose(file);
        return 0;
    }
    for (int t = 0; t < TABLES; t++) {
        Table *table = &valve->table[t];
        size_t size = 1;
        if (!read_ints(file, &table->dimensions, 1) || table->dimensions < 1
            || table->dimensions > MAX_DIMENSIONS) goto broken;
        for (int d = 0; d < table->dimensions; d++) {
            int pair[2];
            if (!read_ints(file, pair, 2) || pair[0] < 0 || pair[0] >= AXES || pair[1] < 1)
                goto broken;
            table->axis[d] = pair[0];
            table->count[d] = pair[1];
            size *= (size_t)pair[1];
        }
        for (int d = 0; d < table->dimensions; d++) {
            table->nodes[d] = malloc(sizeof(double) * (size_t)table->count[d]);
            if (!table->nodes[d] || fread(table->nodes[d], sizeof(double), (size_t)table->count[d],
                                          file) != (size_t)table->count[d]) goto broken;
            if (is_log_axis(table->axis[d]))
                for (int i = 0; i < table->count[d]; i++)
                    table->nodes[d][i] = log(table->nodes[d][i]);
        }
        float *stored = malloc(sizeof(float) * size);
        table->values = malloc(sizeof(double) * size);
        if (!stored || !table->values || fread(stored, sizeof(float), size, file) != size) {
            free(stored);
            goto broken;
        }
        for (size_t i = 0; i < size; i++) table->values[i] = log((double)stored[i]);
        free(stored);
    }
    fclose(file);
    return 1;
broken:
    say(valve, fmi2Error, "%s: truncated or malformed tables", path);
    fclose(file);
    free_tables(valve);
    return 0;
}

/* the nodes along one axis that make a point's value, and their weights (Hermite's cubic with
 * central-difference slopes, Catmull-Rom's on even nodes; linear for 2 or 3 nodes; held for 1) */
static int stencil(const double *nodes, int count, double x, int index[4], double weight[4]) {
    if (x < nodes[0]) x = nodes[0];
    if (x > nodes[count - 1]) x = nodes[count - 1];
    if (count == 1) { index[0] = 0; weight[0] = 1.0; return 1; }
    /* the cell: the last node <= x, at most the second to last */
    int low = 0, high = count - 1;
    while (high - low > 1) {
        int middle = (low + high) / 2;
        if (nodes[middle] <= x) low = middle; else high = middle;
    }
    int cell = low > count - 2 ? count - 2 : low;
    double width = nodes[cell + 1] - nodes[cell];
    double t = (x - nodes[cell]) / width;
    if (count < 4) {
        index[0] = cell; index[1] = cell + 1; weight[0] = 1.0 - t; weight[1] = t;
        return 2;
    }
    int first = cell == 0, last = cell == count - 2;
    /* a missing outer node mirrored across the end node */
    double x_before = first ? nodes[cell] - width : nodes[cell - 1];
    double x_after = last ? nodes[cell + 1] + width : nodes[cell + 2];
    double slope_low = width / (nodes[cell + 1] - x_before);
    double slope_high = width / (x_after - nodes[cell]);
    double t2 = t * t, t3 = t2 * t;
    double h00 = 2 * t3 - 3 * t2 + 1.0, h10 = t3 - 2 * t2 + t;
    double h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    double before = -h10 * slope_low, after = h11 * slope_high;
    double at_low = h00 - h11 * slope_high, at_high = h01 + h10 * slope_low;
    if (first) { at_low += 2 * before; at_high -= before; before = 0.0; }
    if (last) { at_high += 2 * after; at_low -= after; after = 0.0; }
    index[0] = cell > 0 ? cell - 1 : 0; index[1] = cell; index[2] = cell + 1;
    index[3] = cell + 2 < count ? cell + 2 : count - 1;
    weight[0] = before; weight[1] = at_low; weight[2] = at_high; weight[3] = after;
    return 4;
}

/* the table at the point; coordinates by AXIS_*, in SI */
static double lookup(const Table *table, const double coordinate[AXES]) {
    int index[MAX_DIMENSIONS][4], size[MAX_DIMENSIONS], which[MAX_DIMENSIONS];
    double weight[MAX_DIMENSIONS][4], total = 0.0;
    for (int d = 0; d < table->dimensions; d++) {
        int axis = table->axis[d], count = table->count[d];
        double x = coordinate[axis];
        if (is_log_axis(axis)) {  /* held to the range before the logarithm, as in Python */
            double low = exp(table->nodes[d][0]), high = exp(table->nodes[d][count - 1]);
            x = log(x < low ? low : (x > high ? high : x));
        }
        size[d] = stencil(table->nodes[d], count, x, index[d], weight[d]);
        which[d] = 0;
    }
    for (;;) {  /* every combination, the last dimension fastest */
        double w = 1.0;
        size_t offset = 0;
        for (int d = 0; d < table->dimensions; d++) {
            w *= weight[d][which[d]];
            offset = offset * (size_t)table->count[d] + (size_t)index[d][which[d]];
        }
        total += w * table->values[offset];
        int d = table->dimensions - 1;
        while (d >= 0 && ++which[d] == size[d]) which[d--] = 0;
        if (d < 0) break;
    }
    return exp(total);
}

/* the tabulated range [SI] of input i (0 q, 1 p_B, 2 p_P, 3 T): the edge tables' axis */
static void input_range(const Valve *valve, int i, double *low, double *high) {
    const Table *table = &valve->table[U_OPEN];
    *low = -HUGE_VAL; *high = HUGE_VAL;
    for (int d = 0; d < table->dimensions; d++) {
        if (table->axis[d] != INPUT_AXES[i]) continue;
        *low = table->nodes[d][0]; *high = table->nodes[d][table->count[d] - 1];
        if (is_log_axis(table->axis[d])) { *low = exp(*low); *high = exp(*high); }
    }
    if (i == 0) *low = 0.0;  /* below the lowest flow: the cracking valve, held (see above) */
}

/* the inputs held at the edge of the tables now: a bit per input (1 << i) */
static int outside_flags(const Valve *valve) {
    int flags = 0;
    for (int i = 0; i < 4; i++) {
        double low, high;
        input_range(valve, i, &low, &high);
        /* a rounding's worth of slack: the range's own edges are inside */
        double slack = 1e-9 * (fabs(low) + fabs(high));
        if (valve->inputs[i] < low - slack || valve->inputs[i] > high + slack) flags |= 1 << i;
    }
    return flags;
}

/* a warning for each input that has just left the tables' range */
static void warn_outside(Valve *valve, int flags) {
    int entered = flags & ~valve->outside;
    for (int i = 0; i < 4; i++) {
        if (!(entered & (1 << i))) continue;
        double low, high;
        input_range(valve, i, &low, &high);
        say(valve, fmi2Warning, "%s = %.4g %s is outside the tables' %.4g to %.4g %s: the valve "
            "is read at the edge of its tables from here on (output outside = %d)",
            INPUT_NAMES[i], INPUT_FACTORS[i] * valve->inputs[i] + INPUT_OFFSETS[i],
            INPUT_UNITS[i], INPUT_FACTORS[i] * low + INPUT_OFFSETS[i],
            INPUT_FACTORS[i] * high + INPUT_OFFSETS[i], INPUT_UNITS[i], flags);
    }
}

/* the play for the inputs set now: the piston's new state and the outputs */
static int play(const Valve *valve, double *u, double *ratio, double *dp) {
    double at[AXES];
    for (int i = 0; i < 4; i++) if (!isfinite(valve->inputs[i])) return 0;
    at[AXIS_Q] = valve->inputs[0];
    at[AXIS_PB] = valve->inputs[1];
    at[AXIS_PP] = valve->inputs[2];
    at[AXIS_T] = valve->inputs[3];
    double u_open = lookup(&valve->table[U_OPEN], at), u_close = lookup(&valve->table[U_CLOSE], at);
    double dp_open = lookup(&valve->table[DP_OPEN], at);
    double dp_close = lookup(&valve->table[DP_CLOSE], at);
    int opening_lower = u_open <= u_close;
    double low = opening_lower ? u_open : u_close, high = opening_lower ? u_close : u_open;
    double dp_low = opening_lower ? dp_open : dp_close;
    double dp_high = opening_lower ? dp_close : dp_open;
    *u = valve->u;
    *ratio = valve->ratio;
    if (*u < low || *u > high) {
        int pushed_open = *u < low;
        *u = pushed_open ? low : high;
        *dp = pushed_open ? dp_low : dp_high;
        at[AXIS_U] = *u;
        *ratio = *dp / lookup(&valve->table[DP_HELD], at);
    } else {
        at[AXIS_U] = *u;
        *dp = *ratio * lookup(&valve->table[DP_HELD], at);
    }
    return 1;
}

/* ---- FMI 2.0 ---- */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                      const fmi2String categories[]) {
    (void)c; (void)on; (void)n; (void)categories;
    return fmi2OK;
}

static void reset_state(Valve *valve) {
    valve->u = 0.0;
    valve->ratio = 1.0;
    valve->outside = 0;
}

/* the resources folder of a "file:" URI: file:///a/b, file:/a/b or file://localhost/a/b, with
 * %XX escapes */
static void resource_path(const char *uri, char *path, size_t size) {
    const char *p = uri;
    size_t n = 0;
    if (strncmp(p, "file://localhost/", 17) == 0) p += 16;
    else if (strncmp(p, "file:///", 8) == 0) p += 7;
    else if (strncmp(p, "file:/", 6) == 0) p += 5;
    while (*p && n + 1 < size) {
        if (p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            path[n++] = (char)strtol(hex, NULL, 16);
            p += 3;
        } else {
            path[n++] = *p++;
        }
    }
    path[n] = 0;
    if (n > 0 && path[n - 1] == '/') path[--n] = 0;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type type, fmi2String guid,
                                     fmi2String resourceLocation,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn) {
    (void)guid; (void)visible; (void)loggingOn;
    Valve *valve = calloc(1, sizeof(Valve));
    char folder[4096], path[4200];
    if (!valve) return NULL;
    snprintf(valve->instance, sizeof valve->instance, "%s", instanceName ? instanceName : "");
    valve->callbacks = functions;
    if (type != fmi2CoSimulation) {
        say(valve, fmi2Error, "this FMU is for co-simulation only");
        free(valve);
        return NULL;
    }
    if (!resourceLocation) {
        say(valve, fmi2Error, "no resource location: the tables are in the FMU's resources");
        free(valve);
        return NULL;
    }
    resource_path(resourceLocation, folder, sizeof folder);
    snprintf(path, sizeof path, "%s/tables.bin", folder);
    if (!load_tables(valve, path)) { free(valve); return NULL; }
    valve->loaded = 1;
    valve->inputs[0] = 1e-4; valve->inputs[1] = 5e5; valve->inputs[2] = 8e6;
    valve->inputs[3] = 313.15;
    reset_state(valve);
    return valve;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    Valve *valve = c;
    if (!valve) return;
    free_tables(valve);
    free(valve);
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                      fmi2Real tolerance, fmi2Real startTime,
                                      fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)c; (void)toleranceDefined; (void)tolerance; (void)startTime; (void)stopTimeDefined;
    (void)stopTime;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    reset_state((Valve *)c);
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              fmi2Real value[]) {
    Valve *valve = c;
    double u = 0.0, ratio = 1.0, dp = 0.0;
    int computed = 0;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] < 4) { value[i] = valve->inputs[vr[i]]; continue; }
        if (vr[i] >= VARIABLES) {
            say(valve, fmi2Error, "no variable with value reference %u", vr[i]);
            return fmi2Error;
        }
        if (!computed) {
            if (!play(valve, &u, &ratio, &dp)) {
                say(valve, fmi2Error, "an input is not a finite number");
                return fmi2Error;
            }
            computed = 1;
        }
        value[i] = vr[i] == VR_PL ? valve->inputs[1] + dp : (vr[i] == VR_DP ? dp : u);
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                              const fmi2Real value[]) {
    Valve *valve = c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= 4) {
            say(valve, fmi2Error, "value reference %u is not an input", vr[i]);
            return fmi2Error;
        }
        valve->inputs[vr[i]] = value[i];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Integer value[]) {
    Valve *valve = c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_OUTSIDE) {
            say(valve, fmi2Error, "no Integer variable with value reference %u", vr[i]);
            return fmi2Error;
        }
        value[i] = outside_flags(valve);  /* the inputs set now, as the Real outputs */
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Boolean value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Integer value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}

/* the play's state is two numbers, but saving it is not offered (canGetAndSetFMUstate false) */
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c; (void)s; (void)n;
    return fmi2Error;
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi2Error;
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                          fmi2FMUstate *s) {
    (void)c; (void)b; (void)n; (void)s;
    return fmi2Error;
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[], size_t nz,
                                               const fmi2Real dv[], fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fmi2Error;
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Valve *valve = c;
    double u, ratio, dp;
    (void)t; (void)h; (void)noSetPrior;
    if (!play(valve, &u, &ratio, &dp)) {
        say(valve, fmi2Error, "an input is not a finite number");
        return fmi2Error;
    }
    valve->u = u;
    valve->ratio = ratio;
    int flags = outside_flags(valve);
    warn_outside(valve, flags);
    valve->outside = flags;
    return fmi2OK;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                       fmi2Integer *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                       fmi2Boolean *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
