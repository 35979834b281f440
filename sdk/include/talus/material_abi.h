/*
 * talus/material_abi.h -- the Talus material plugin contract (C99).
 *
 * This is the only file the Talus core and a material plugin share. A plugin
 * is a shared library that exports exactly one symbol, talus_material_entry;
 * the host (the MPM solver, the material-point driver, `talus plugin check`)
 * loads it with dlopen and talks to it only through the structures below.
 * docs/abi.md is this header in prose.
 *
 * Versioning
 *   TALUS_ABI_VERSION_MAJOR changes on any incompatible change; a plugin must
 *   refuse a host of another major, and the host refuses a plugin of another
 *   major. TALUS_ABI_VERSION_MINOR grows when fields, flags or functions are
 *   appended; nothing is ever removed, reordered or given a new meaning
 *   within a major. Every structure starts with `struct_size` (bytes, filled
 *   by whoever allocates the structure), so each side learns which fields the
 *   other knows: a reader tests TALUS_HAS_FIELD before reading a field newer
 *   than 1.0, and treats a missing one as its documented default (NULL, 0).
 *   Arrays of descriptors are arrays of pointers, never of structures, so
 *   that a larger (newer) structure never shifts its neighbours. Thus a 1.0
 *   plugin runs in a 1.1 host unchanged, and a 1.1 plugin that uses none of
 *   the 1.1 model flags or parameter types runs in a 1.0 host (which refuses,
 *   naming it, any flag or type it does not know).
 *
 * Conventions (frozen by tests; changing any of them is a new major)
 *   - Stress is Cauchy stress, tension positive, in Pa (any consistent unit
 *     system works; the shipped plugins document SI).
 *   - Symmetric tensors travel as 6 doubles in Voigt order
 *       [0]=xx [1]=yy [2]=zz [3]=xy [4]=yz [5]=xz.
 *   - Strain increments use engineering shear: [3] = 2*eps_xy, and so on.
 *     Stress uses the tensor components: [3] = sigma_xy.
 *   - The deformation gradient F is a row-major 3x3: F[3*i + j] = F_ij; so
 *     is the rotation of an increment (ABI 1.1).
 *   - A 2D (plane strain) host still passes full 3D arrays, with zero
 *     out-of-plane strain increments, so a plugin never knows the dimension.
 *   - The consistent tangent is row-major 6x6:
 *       tangent[6*i + j] = d stress_end[i] / d strain_increment[j]
 *     with the increment in Voigt engineering-shear form.
 *   - Objectivity: for a model without TALUS_MODEL_FINITE_STRAIN the host
 *     has already rotated stress_start objectively into the configuration at
 *     the end of the increment (Hughes-Winget: the rotation the batch's
 *     `rotation` field carries), so the model works on the strain increment
 *     alone; a model with tensor-valued state variables rotates them itself
 *     with `rotation` (TALUS_MODEL_WANTS_ROTATION). A model with
 *     TALUS_MODEL_FINITE_STRAIN computes stress from F and owns its
 *     objectivity; the host passes stress_start unrotated.
 *   - density[i] is the current mass density at the end of the increment.
 *     Density is a material property owned by the host (it makes the particle
 *     mass); a plugin must not declare it as a parameter.
 *   - Identifiers (parameter keys, state names, model ids, library names) are
 *     lower_snake_case. A model id is unique within its library, a library
 *     name among the libraries a host loads; "library/model" is the model's
 *     qualified id, which never collides. Users may write the model id alone
 *     while only one loaded library offers it.
 *
 * Threads and resources (each function below repeats its own contract)
 *   The entry point, create, create_ex, instance_state and destroy are called
 *   at set-up or tear-down, from one thread at a time. update and init_state
 *   must be reentrant: the host calls them concurrently from several threads
 *   on disjoint batches of the same instance -- unless the model sets
 *   TALUS_MODEL_NOT_REENTRANT, in which case the host never runs two calls
 *   into the same library at once (Fortran code with SAVE or COMMON data
 *   needs this). update and init_state must not allocate, do I/O other than
 *   through the host's log callback, change the floating-point environment,
 *   or let an exception (or longjmp) escape. Strings in descriptors are UTF-8
 *   and must stay valid until the library is unloaded.
 *
 * Aliasing
 *   stress_end may be the same array as stress_start, and state_end the same
 *   as state_start: a plugin must read every input of point i before it
 *   writes any output of point i. Different points never share storage.
 */
#ifndef TALUS_MATERIAL_ABI_H
#define TALUS_MATERIAL_ABI_H

#include <stddef.h>
#include <stdint.h>

#define TALUS_ABI_VERSION_MAJOR 1
#define TALUS_ABI_VERSION_MINOR 2

/* Whether the structure *ptr (of type `type`, which starts with
 * struct_size) holds `field`: its writer knew the field. Test this before
 * reading any field appended after ABI 1.0. */
#define TALUS_HAS_FIELD(type, ptr, field)                                                          \
    ((ptr)->struct_size >= offsetof(type, field) + sizeof(((const type *)0)->field))

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

/* Levels of the host's log callback (ABI 1.1). */
#define TALUS_LOG_INFO 0
#define TALUS_LOG_WARNING 1

/* What the host tells the plugin about itself when it calls the entry. The
 * structure lives only during the call: a plugin that wants the callbacks
 * later copies the pointers (they stay valid until the library is
 * unloaded). */
typedef struct talus_host_info {
    uint32_t struct_size;
    uint32_t abi_major; /* the host's TALUS_ABI_VERSION_MAJOR */
    uint32_t abi_minor; /* the host's TALUS_ABI_VERSION_MINOR */
    uint32_t reserved0;
    const char *host_name; /* e.g. "talus 0.1.0" */

    /* ---- ABI 1.1 ---- */
    /* Reports something worth a user's attention without failing (a point
     * whose initial stress was brought back to the yield surface, a
     * parameter combination that is valid but unusual). Callable from any
     * thread at any time after the entry returned, including inside update;
     * pass log_context back unchanged. The host labels each message with
     * the library, shows the first ones and counts repeats, so a plugin may
     * report per point without flooding the user. message: UTF-8, one line. */
    void (*log)(void *log_context, int32_t level, const char *message);
    void *log_context;
    /* A host capability by its id ("vendor.name"), or NULL when the host
     * does not offer it. No host extension is defined in 1.1; the hook is
     * here so that later ones need no new minor to be discovered. Any
     * thread. */
    const void *(*get_extension)(const char *extension_id);
} talus_host_info;

/* ---- parameters: the numbers a user gives a material in YAML ---- */

/* Parameter types. A scalar value travels as a double; the host checks that
 * an INTEGER is integral and that a BOOLEAN is 0 or 1 (YAML false/true). */
#define TALUS_PARAM_REAL 0u
#define TALUS_PARAM_INTEGER 1u
#define TALUS_PARAM_BOOLEAN 2u
/* ABI 1.1, for models with create_ex only: a list of reals (each within
 * min_value..max_value, between min_count and max_count of them; YAML: a
 * sequence), and a string (YAML: a scalar; e.g. a file name, resolved by
 * the model against talus_create_args.base_dir). */
#define TALUS_PARAM_REAL_ARRAY 3u
#define TALUS_PARAM_STRING 4u

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

    /* ---- ABI 1.1 ---- */
    /* REAL_ARRAY: how many values the user may give (max_count 0: no upper
     * limit). When not REQUIRED the default is the empty list, so min_count
     * is then 0. min_count is at most 65536. The typical value of a REQUIRED list is max(min_count,
     * 1) copies of typical_value; that of an optional list is the empty list. */
    uint32_t min_count;
    uint32_t max_count;
    /* STRING: the value when the user omits it (not REQUIRED; NULL means
     * ""), and an example for the documentation (NULL: none; then the
     * conformance checks need the user to supply a value). */
    const char *default_string;
    const char *typical_string;
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

/* The state layout of one instance (ABI 1.1, TALUS_MODEL_INSTANCE_STATE):
 * filled by the model's instance_state. The descriptors must stay valid
 * until the instance is destroyed. */
typedef struct talus_state_layout {
    uint32_t struct_size; /* set by the host */
    uint32_t n_state;     /* entries in state */
    const talus_state_desc *const *state;
} talus_state_layout;

/* ---- creating an instance from parameter values (ABI 1.1) ---- */

/* One parameter's value, of the type its descriptor declares. */
typedef struct talus_param_value {
    uint32_t struct_size;
    uint32_t type;       /* the descriptor's TALUS_PARAM_* type */
    uint64_t count;      /* REAL_ARRAY: number of reals; STRING: bytes
                            without the NUL; scalars: 1 */
    double scalar;       /* REAL, INTEGER, BOOLEAN */
    const double *reals; /* REAL_ARRAY: `count` values (NULL when 0) */
    const char *string;  /* STRING: NUL-terminated UTF-8 */
} talus_param_value;

typedef struct talus_create_args {
    uint32_t struct_size;
    uint32_t n_values;                      /* entries in values: the model's n_params */
    const talus_param_value *const *values; /* in the order of params, checked
                                               by the host against the table */
    const char *material_name;              /* the user's name for the material, for messages */
    const char *base_dir;                   /* the folder of the file the material was read
                                               from (absolute), for relative paths in string
                                               parameters; "" when there is none */
} talus_create_args;

/* ---- the per-call batch of points ---- */

#define TALUS_BATCH_WANT_WAVE_SPEED 1u /* fill wave_speed */
#define TALUS_BATCH_WANT_TANGENT 2u    /* fill tangent */
/* ABI 1.2: the host has made sure that every input value of this call is
 * finite -- strain_increment, F_start, F_end, stress_start, state_start --
 * and every density positive and finite (its own screened outputs of the
 * step before, and its kinematics, tested there), so the plugin may leave
 * out its own screen of them. A host that cannot say so leaves the flag
 * off; a plugin may ignore it (1.0 and 1.1 plugins do). The host screens
 * the outputs (stress, state, wave speeds, tangent) whatever the flag. */
#define TALUS_BATCH_INPUTS_FINITE 4u

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

    /* ---- ABI 1.1: where and when the points are ---- */
    int64_t step;                        /* the step being computed, 1 for the first; 0 at
                                            set-up (init_state and the dt = 0 call) */
    const int64_t *point_id;             /* n: each point's stable id (the
                                            particle id; the driver: 0) */
    const double *characteristic_length; /* n: the length a regularised
                                            softening law scales with (UMAT's
                                            CELENT): the geometric mean of the
                                            edges of the background cell, in
                                            the analysis' dimension */
    const double *rotation;              /* n x 9, row-major, with
                                            TALUS_MODEL_WANTS_ROTATION (else
                                            NULL): the increment's rotation Q
                                            (UMAT's DROT); the host's rotated
                                            stress_start is Q s Q^T */
} talus_batch;

/* ---- models and libraries ---- */

/* Model flags. */
#define TALUS_MODEL_FINITE_STRAIN 1u /* computes stress from F (see above) */
#define TALUS_MODEL_TANGENT 2u       /* honours TALUS_BATCH_WANT_TANGENT */
/* ABI 1.1: */
/* update and init_state are not reentrant: the host never runs two calls
 * into this model's library at once. */
#define TALUS_MODEL_NOT_REENTRANT 4u
/* The state layout is the instance's (instance_state), not the model's
 * descriptor's: e.g. a generic adapter whose state size is a parameter. */
#define TALUS_MODEL_INSTANCE_STATE 8u
/* The host fills talus_batch.rotation. */
#define TALUS_MODEL_WANTS_ROTATION 16u

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
     * reject combinations of values with TALUS_STATUS_FAILED and a message.
     * Set-up, one thread at a time. A 1.1 host calls create_ex instead when
     * the model has it; create is still required so that a 1.0 host can run
     * a model whose parameters are all scalars (a model with array or string
     * parameters may make create fail with a message). */
    int32_t (*create)(const double *param_values, uint32_t n_values, talus_instance **instance,
                      talus_error *error);
    /* Release an instance. Tear-down, one thread at a time, after every
     * call on the instance has returned. */
    void (*destroy)(talus_instance *instance);

    /* Advance every point of the batch over one increment. Reentrant
     * (concurrent calls on disjoint batches of one instance) unless the model
     * sets TALUS_MODEL_NOT_REENTRANT. */
    int32_t (*update)(const talus_instance *instance, const talus_batch *batch, talus_error *error);

    /* ---- ABI 1.1 (each may be NULL) ---- */

    /* create from typed values (talus_create_args); required when a
     * parameter is a REAL_ARRAY or a STRING. Set-up, one thread at a time. */
    int32_t (*create_ex)(const talus_create_args *args, talus_instance **instance,
                         talus_error *error);

    /* With TALUS_MODEL_INSTANCE_STATE (required then): the instance's state
     * layout, asked once after create. The model descriptor's own n_state and
     * state are then ignored. Set-up, one thread at a time. */
    int32_t (*instance_state)(const talus_instance *instance, talus_state_layout *layout,
                              talus_error *error);

    /* Bring each point's initial state to a start the model accepts, once
     * before the first step (and again whenever a point takes up this
     * material). The batch is an update's with dt = 0, a zero strain
     * increment, F_start = F_end, step = 0, stress_start the initial stress
     * the user gave (e.g. geostatic) and state_start the initial state
     * (descriptor values and the user's initial_state). It writes
     * stress_end and state_end, and wave_speed when asked. A model whose
     * state depends on the stress (a hardening variable, a void ratio) sets
     * it here. An initial stress outside the model's elastic domain must not
     * pass silently: either return it to the domain and report it through
     * the host's log (how many points, how far), or fail naming the point.
     * With init_state the host makes no other set-up call; without it, a
     * 1.1 host makes the set-up call through update (dt = 0), as a 1.0 host
     * does. Concurrency as update. */
    int32_t (*init_state)(const talus_instance *instance, const talus_batch *batch,
                          talus_error *error);
} talus_model;

typedef struct talus_library {
    uint32_t struct_size;
    uint32_t abi_major; /* the TALUS_ABI_VERSION_MAJOR it was built with */
    uint32_t abi_minor; /* the TALUS_ABI_VERSION_MINOR it was built with */
    uint32_t n_models;
    const char *name;    /* library name: lower_snake_case, the prefix of its
                            models' qualified ids (library/model) */
    const char *version; /* library version */
    const talus_model *const *models;

    /* ---- ABI 1.1 ---- */
    /* A plugin capability by its id ("vendor.name"), or NULL when the
     * library does not offer it; may itself be NULL. Hosts ask only for ids
     * they know; none is defined in 1.1. Any thread. */
    const void *(*get_extension)(const char *extension_id);
} talus_library;

/* The entry point. The plugin checks host->abi_major and returns
 * TALUS_STATUS_FAILED with a message naming both versions if it differs from
 * its own (and likewise when it needs a newer host minor than
 * host->abi_minor); otherwise it stores a pointer to its (static) library
 * descriptor in *library and returns TALUS_STATUS_OK. Called once per load,
 * from one thread, before any other call. */
typedef int32_t (*talus_material_entry_fn)(const talus_host_info *host,
                                           const talus_library **library, talus_error *error);

#ifdef __cplusplus
}
#endif

#endif /* TALUS_MATERIAL_ABI_H */
