/*
 * talus/material_abi.h -- the Talus material plugin contract (C99).
 *
 * This is the only file the Talus core and a material plugin share. A plugin
 * is a shared library that exports exactly one symbol, talus_material_entry;
 * the host (the MPM solver, the material-point driver, `talus plugin check`)
 * loads it with dlopen and talks to it only through the structures below.
 *
 * Versioning
 *   TALUS_ABI_VERSION_MAJOR changes on any incompatible change; a plugin must
 *   refuse a host of another major. TALUS_ABI_VERSION_MINOR grows when fields
 *   are appended. Every structure starts with `struct_size` (bytes, filled by
 *   whoever allocates the structure) and fields are only ever appended, so a
 *   reader compares struct_size against the offset of a field before reading
 *   it. Arrays of descriptors are arrays of pointers, never of structures, so
 *   that a larger (newer) structure never shifts its neighbours.
 *
 * Conventions (frozen by tests; changing any of them is a new major)
 *   - Stress is Cauchy stress, tension positive, in Pa (any consistent unit
 *     system works; the shipped plugins document SI).
 *   - Symmetric tensors travel as 6 doubles in Voigt order
 *       [0]=xx [1]=yy [2]=zz [3]=xy [4]=yz [5]=xz.
 *   - Strain increments use engineering shear: [3] = 2*eps_xy, and so on.
 *     Stress uses the tensor components: [3] = sigma_xy.
 *   - The deformation gradient F is a row-major 3x3: F[3*i + j] = F_ij.
 *   - A 2D (plane strain) host still passes full 3D arrays, with zero
 *     out-of-plane strain increments, so a plugin never knows the dimension.
 *   - The consistent tangent is row-major 6x6:
 *       tangent[6*i + j] = d stress_end[i] / d strain_increment[j]
 *     with the increment in Voigt engineering-shear form.
 *   - Objectivity: for a model without TALUS_MODEL_FINITE_STRAIN the host
 *     has already rotated stress_start objectively into the configuration at
 *     the end of the increment, so the model works on the strain increment
 *     alone. A model with TALUS_MODEL_FINITE_STRAIN computes stress from F
 *     and owns its objectivity; the host passes stress_start unrotated.
 *   - density[i] is the current mass density at the end of the increment.
 *     Density is a material property owned by the host (it makes the particle
 *     mass); a plugin must not declare it as a parameter.
 *
 * Threading and resources
 *   create/destroy are called at set-up from one thread. update must be
 *   reentrant: the host calls it concurrently from several threads on
 *   disjoint batches of the same instance. update must not allocate, do I/O,
 *   change the floating-point environment, or let an exception (or longjmp)
 *   escape. Strings in descriptors are UTF-8 and must stay valid until the
 *   library is unloaded.
 *
 * Aliasing
 *   stress_end may be the same array as stress_start, and state_end the same
 *   as state_start: a plugin must read every input of point i before it
 *   writes any output of point i. Different points never share storage.
 */
#ifndef TALUS_MATERIAL_ABI_H
#define TALUS_MATERIAL_ABI_H

#include <stdint.h>

#define TALUS_ABI_VERSION_MAJOR 1
#define TALUS_ABI_VERSION_MINOR 0

/* The name of the single exported entry point. */
#define TALUS_MATERIAL_ENTRY_SYMBOL "talus_material_entry"

#if defined(_WIN32)
#define TALUS_PLUGIN_VISIBLE __declspec(dllexport)
#else
#define TALUS_PLUGIN_VISIBLE __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
#define TALUS_EXTERN_C extern "C"
#else
#define TALUS_EXTERN_C
#endif

/* Put this in front of the definition of talus_material_entry. */
#define TALUS_PLUGIN_EXPORT TALUS_EXTERN_C TALUS_PLUGIN_VISIBLE

#ifdef __cplusplus
extern "C" {
#endif

/* ---- status codes returned by the entry point, create and update ---- */

/* Success. */
#define TALUS_STATUS_OK 0
/* Failure: error->message says why; for update, error->point_index names the
 * failing point (its index in the batch) or is -1. The outputs of the batch
 * are then undefined. */
#define TALUS_STATUS_FAILED 1
/* update only: the increment is too large for this model (e.g. a local
 * return mapping did not converge). error->cut_factor in (0, 1) suggests the
 * factor by which the host should shrink dt before retrying, as UMAT's PNEWDT.
 * The outputs of the batch are then undefined. */
#define TALUS_STATUS_CUT_STEP 2

/* Size of the message buffer in talus_error, including the terminating NUL. */
#define TALUS_ERROR_MESSAGE_SIZE 1024

/* Filled by the host (struct_size, zeros elsewhere) and written by the plugin
 * when it returns anything but TALUS_STATUS_OK. */
typedef struct talus_error {
    uint32_t struct_size;
    uint32_t reserved0;
    int64_t point_index;                    /* failing point in the batch, or -1 */
    double cut_factor;                      /* with TALUS_STATUS_CUT_STEP: suggested dt factor */
    char message[TALUS_ERROR_MESSAGE_SIZE]; /* NUL-terminated UTF-8 */
} talus_error;

/* What the host tells the plugin about itself when it calls the entry. */
typedef struct talus_host_info {
    uint32_t struct_size;
    uint32_t abi_major; /* the host's TALUS_ABI_VERSION_MAJOR */
    uint32_t abi_minor; /* the host's TALUS_ABI_VERSION_MINOR */
    uint32_t reserved0;
    const char *host_name; /* e.g. "talus 0.1.0" */
} talus_host_info;

/* ---- parameters: the numbers a user gives a material in YAML ---- */

/* Parameter types. Every value travels as a double; the host checks that an
 * INTEGER is integral and that a BOOLEAN is 0 or 1 (YAML false/true). */
#define TALUS_PARAM_REAL 0u
#define TALUS_PARAM_INTEGER 1u
#define TALUS_PARAM_BOOLEAN 2u

/* Parameter flags. */
#define TALUS_PARAM_REQUIRED 1u      /* no default: the user must give it */
#define TALUS_PARAM_MIN_EXCLUSIVE 2u /* value > min_value, not >= */
#define TALUS_PARAM_MAX_EXCLUSIVE 4u /* value < max_value, not <= */

typedef struct talus_param_desc {
    uint32_t struct_size;
    uint32_t type;  /* TALUS_PARAM_REAL / INTEGER / BOOLEAN */
    uint32_t flags; /* TALUS_PARAM_* flags */
    uint32_t reserved0;
    const char *key;      /* YAML key: lower_snake_case, unique in the model */
    const char *unit;     /* SI unit, e.g. "Pa", "deg", "-" for dimensionless */
    const char *doc;      /* one sentence for users */
    double default_value; /* used when the user omits it (not REQUIRED) */
    double min_value;     /* lower bound; -HUGE_VAL when unbounded */
    double max_value;     /* upper bound; +HUGE_VAL when unbounded */
    double typical_value; /* a representative valid value, used by the
                             conformance checks and as the documented example */
} talus_param_desc;

/* ---- state variables: per-point internal variables ---- */

#define TALUS_STATE_OUTPUT 1u    /* worth writing to output files */
#define TALUS_STATE_USER_INIT 2u /* the user may set its initial value */

typedef struct talus_state_desc {
    uint32_t struct_size;
    uint32_t flags; /* TALUS_STATE_* flags */
    uint32_t size;  /* number of doubles (1 for a scalar, 6 for a tensor) */
    uint32_t reserved0;
    const char *name;     /* lower_snake_case, unique in the model */
    const char *unit;     /* SI unit or "-" */
    const char *doc;      /* one sentence for users */
    double initial_value; /* value of every component before the first step */
} talus_state_desc;

/* ---- the per-call batch of points ---- */

#define TALUS_BATCH_WANT_WAVE_SPEED 1u /* fill wave_speed */
#define TALUS_BATCH_WANT_TANGENT 2u    /* fill tangent */

/* Arrays hold n_points consecutive records: point i's strain increment is
 * strain_increment[6*i .. 6*i+5], its F_end is F_end[9*i .. 9*i+8], and its
 * state is state_start[state_size*i .. state_size*(i+1)-1]. */
typedef struct talus_batch {
    uint32_t struct_size;
    uint32_t flags;      /* TALUS_BATCH_* flags */
    uint32_t state_size; /* doubles of state per point: the model's total */
    uint32_t reserved0;
    uint64_t n_points;
    double time;                    /* time at the start of the increment */
    double dt;                      /* length of the increment */
    const double *strain_increment; /* n x 6, Voigt, engineering shear */
    const double *F_start;          /* n x 9, row-major */
    const double *F_end;            /* n x 9, row-major */
    const double *density;          /* n, at the end of the increment */
    const double *stress_start;     /* n x 6, Voigt, Cauchy, tension + */
    const double *state_start;      /* n x state_size (NULL if size 0) */
    double *stress_end;             /* n x 6, written by the plugin */
    double *state_end;              /* n x state_size (NULL if size 0) */
    double *wave_speed;             /* n; with TALUS_BATCH_WANT_WAVE_SPEED: the
                                       largest elastic wave speed at the end
                                       state (for the host's time step) */
    double *tangent;                /* n x 36; with TALUS_BATCH_WANT_TANGENT */
} talus_batch;

/* ---- models and libraries ---- */

/* Model flags. */
#define TALUS_MODEL_FINITE_STRAIN 1u /* computes stress from F (see above) */
#define TALUS_MODEL_TANGENT 2u       /* honours TALUS_BATCH_WANT_TANGENT */

/* Opaque per-material instance, created from one set of parameter values. */
typedef struct talus_instance talus_instance;

typedef struct talus_model {
    uint32_t struct_size;
    uint32_t flags;      /* TALUS_MODEL_* flags */
    uint32_t n_params;   /* entries in params */
    uint32_t n_state;    /* entries in state */
    const char *id;      /* stable id used in YAML: lower_snake_case */
    const char *name;    /* display name */
    const char *version; /* the model's own version, e.g. "1.0.0" */
    const char *doc;     /* a paragraph for users, with the reference */
    const talus_param_desc *const *params;
    const talus_state_desc *const *state;

    /* Make an instance from n_values parameter values, in the order of
     * params, already checked by the host against type and bounds. May
     * reject combinations of values with TALUS_STATUS_FAILED and a message. */
    int32_t (*create)(const double *param_values, uint32_t n_values, talus_instance **instance,
                      talus_error *error);
    void (*destroy)(talus_instance *instance);

    /* Advance every point of the batch over one increment. */
    int32_t (*update)(const talus_instance *instance, const talus_batch *batch, talus_error *error);
} talus_model;

typedef struct talus_library {
    uint32_t struct_size;
    uint32_t abi_major; /* the TALUS_ABI_VERSION_MAJOR it was built with */
    uint32_t abi_minor; /* the TALUS_ABI_VERSION_MINOR it was built with */
    uint32_t n_models;
    const char *name;    /* library name, for messages */
    const char *version; /* library version */
    const talus_model *const *models;
} talus_library;

/* The entry point. The plugin checks host->abi_major and returns
 * TALUS_STATUS_FAILED with a message naming both versions if it differs from
 * its own; otherwise it stores a pointer to its (static) library descriptor
 * in *library and returns TALUS_STATUS_OK. */
typedef int32_t (*talus_material_entry_fn)(const talus_host_info *host,
                                           const talus_library **library, talus_error *error);

#ifdef __cplusplus
}
#endif

#endif /* TALUS_MATERIAL_ABI_H */
